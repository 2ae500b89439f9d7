//! The one registry of schemes: the built-in ones, each declared in its own file, then any a program adds with
//! [`register`]. A scheme's [`Kind`] is its place here: the `scheme` byte of its rounds' datagrams, and the order of
//! every table's estimator columns. Adding a scheme is one file (an [`Estimator`]) and one registration.

use std::sync::{Arc, RwLock};

use super::{centralized, ci, diffusion, hcmci, icf, kcf, local, sequeira, Context, Estimator};
use crate::checks::Checks;
use crate::estimate::{Gaussian, MissingChannels};

/// One scheme as `simnet estimators` lists it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Scheme {
    /// Its name in topology files and `--estimators`.
    pub name: &'static str,
    /// The source document and equations it implements.
    pub reference: &'static str,
    /// What each round carries.
    pub messages: &'static str,
    /// Its `[estimators]` parameters.
    pub parameters: &'static str,
}

/// How a node builds its instance of a built-in scheme: from its place in the network, the initial estimate, how
/// missing measurement rows are treated, and the `[estimators]` parameters.
pub type Builder = fn(Context, Gaussian, MissingChannels, &Params) -> Box<dyn Estimator>;

/// How a scheme a program registered is set up, once per scenario, from its own table (`[estimators.<name>]`,
/// empty when the file has none): its problems reported on the checks by key (`estimators.<name>.<key>`), and the
/// function that builds each node's instance with the parameters it read.
pub type Configure = fn(&toml::Table, &mut Checks) -> NodeBuilder;

/// Builds one node's instance of a configured scheme: from its place in the network, the initial estimate and how
/// missing measurement rows are treated.
pub type NodeBuilder = Arc<dyn Fn(Context, Gaussian, MissingChannels) -> Box<dyn Estimator> + Send + Sync>;

/// A registered scheme as a scenario set it up: its table as the file holds it, and the builder it made.
#[derive(Clone)]
pub struct Configured {
    /// `[estimators.<name>]` as written (what the scenario writes back).
    pub table: toml::Table,
    /// Each node's instance, with the parameters read from `table`.
    pub build: NodeBuilder,
}

impl std::fmt::Debug for Configured {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Configured")
            .field("table", &self.table)
            .finish_non_exhaustive()
    }
}

/// Two set-ups are one when their tables are: the builder is the scheme's function of its table.
impl PartialEq for Configured {
    fn eq(&self, other: &Configured) -> bool {
        self.table == other.table
    }
}

/// Who runs a scheme.
#[derive(Clone, Copy)]
pub(super) enum Role {
    /// The node's own two filters (`independent`: [`super::Local`], `sequeira`: [`super::Sequeira`]), finished at
    /// the step's deadline with the measurements it heard.
    Filters,
    /// One fusion center, hosted by the observer (`centralized`, `centralized-net`).
    Center,
    /// Every node, over the step's rounds: built by the node with this.
    Node(Builder),
    /// Every node, over the step's rounds: a program's scheme, set up from its own table.
    Configured(Configure),
}

/// A scheme and who runs it.
pub(super) struct Registration {
    pub scheme: Scheme,
    pub role: Role,
}

/// The built-in schemes, in registry order.
const BUILTIN: [&Registration; 9] = [
    &local::REGISTRATION,
    &sequeira::REGISTRATION,
    &centralized::REGISTRATION,
    &centralized::NET_REGISTRATION,
    &kcf::REGISTRATION,
    &icf::REGISTRATION,
    &hcmci::REGISTRATION,
    &diffusion::REGISTRATION,
    &ci::REGISTRATION,
];

/// The schemes a program registered, after the built-in ones.
static ADDED: RwLock<Vec<&'static Registration>> = RwLock::new(Vec::new());

/// Why a scheme cannot be registered.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RegisterError {
    /// The name is a registered scheme's (its kind given), or `all`.
    #[error("an estimator named `{name}` is registered already")]
    Taken {
        /// The name.
        name: &'static str,
        /// The scheme holding it (none for `all`).
        kind: Option<Kind>,
    },
    /// Not a name a topology file can hold.
    #[error("`{0}` is not an estimator name (lower-case letters, digits and `-`, starting with a letter)")]
    Name(&'static str),
    /// 256 schemes are registered: the wire's scheme byte has no room for another.
    #[error("256 estimators are registered; there is no room for `{0}`")]
    Full(&'static str),
}

/// Registers a scheme every node runs over the step's rounds, set up by `configure` from its own table
/// (`[estimators.<name>]` in a topology file, `estimators.<name>.<key>` for `--set` and sweeps; empty when the file
/// has none): from now on `name` is a scheme like the built-in ones — in topology files and overrides, on the wire,
/// in the summary's `estimators`, in `trace.csv` and the plots, and `simnet estimators` lists it with its
/// `parameters`. Every process of a run must register the same schemes in the same order (the kind is the wire's
/// scheme byte).
///
/// A scheme of your own, here the node's own Kalman filter (which must agree with `independent` to the last digit),
/// run beside the built-in ones:
///
/// ```
/// use std::sync::Arc;
/// use simnet_core::estimate::{EstimateError, Gaussian, MissingChannels};
/// use simnet_core::estimators::{register, Estimator, Message, Scheme, StepInput};
///
/// struct Own {
///     g: Gaussian,
///     policy: MissingChannels,
/// }
///
/// impl Estimator for Own {
///     fn name(&self) -> &'static str {
///         "own"
///     }
///     fn state(&self) -> Option<&Gaussian> {
///         Some(&self.g)
///     }
///     fn state_mut(&mut self) -> Option<&mut Gaussian> {
///         Some(&mut self.g)
///     }
///     fn message(&self, _round: usize) -> Option<Message> {
///         None
///     }
///     fn combine(&mut self, _: usize, _: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
///         Ok(())
///     }
///     fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
///         if let Some(m) = input.own {
///             self.g = input.update(&self.g, input.node, m, self.policy)?;
///         }
///         Ok(())
///     }
/// }
///
/// let scheme = Scheme { name: "own", reference: "a test", messages: "none", parameters: "-" };
/// // No parameters: its table is not read; each node's instance starts from the node's prior.
/// let own = register(scheme, |_, _| Arc::new(|_, g, policy| Box::new(Own { g, policy })))?;
/// assert_eq!(own.name(), "own");
/// assert_eq!(simnet_core::estimators::Kind::from_name("own"), Some(own));
/// assert!(own.takes_table() && !simnet_core::estimators::Kind::Kcf.takes_table());
/// assert!(register(scheme, |_, _| Arc::new(|_, g, policy| Box::new(Own { g, policy }))).is_err()); // one name, one scheme
/// let bad = Scheme { name: "Own 2", ..scheme };
/// assert!(register(bad, |_, _| Arc::new(|_, g, policy| Box::new(Own { g, policy }))).is_err()); // not a name a file can hold
/// assert_eq!(simnet_core::estimators::Kind::from_id(own.id() + 1), None); // nothing registered there
/// # Ok::<(), simnet_core::estimators::RegisterError>(())
/// ```
///
/// `simnet::Sim` then runs it like any other (the `simnet` crate's `sim` module shows a run, and a scheme that
/// reads its own parameters).
pub fn register(scheme: Scheme, configure: Configure) -> Result<Kind, RegisterError> {
    let name = scheme.name;
    if !crate::text::is_name(name) {
        return Err(RegisterError::Name(name));
    }
    if name == "all" {
        return Err(RegisterError::Taken { name, kind: None });
    }
    let mut added = ADDED.write().unwrap_or_else(|e| e.into_inner());
    let taken = BUILTIN.iter().chain(added.iter()).position(|r| r.scheme.name == name);
    if let Some(i) = taken {
        return Err(RegisterError::Taken {
            name,
            kind: Some(Kind(i as u8)),
        });
    }
    let id = u8::try_from(BUILTIN.len() + added.len()).map_err(|_| RegisterError::Full(name))?;
    added.push(Box::leak(Box::new(Registration {
        scheme,
        role: Role::Configured(configure),
    })));
    Ok(Kind(id))
}

/// Every registered scheme, in registry order.
pub fn schemes() -> Vec<Scheme> {
    Kind::all().into_iter().map(Kind::scheme).collect()
}

/// A registered scheme: its place in the registry.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Kind(u8);

#[allow(non_upper_case_globals)]
impl Kind {
    /// The node's own filter, nothing exchanged.
    pub const Independent: Kind = Kind(0);
    /// The β-weighted consensus of Sequeira (2023).
    pub const Sequeira: Kind = Kind(1);
    /// The centralized filter over every measurement, delivered whole.
    pub const Centralized: Kind = Kind(2);
    /// The centralized filter at a sink, over the lossy links.
    pub const CentralizedNet: Kind = Kind(3);
    /// The Kalman consensus filter.
    pub const Kcf: Kind = Kind(4);
    /// The information consensus filter.
    pub const Icf: Kind = Kind(5);
    /// Hybrid consensus on measurements and information.
    pub const Hcmci: Kind = Kind(6);
    /// Diffusion Kalman filtering.
    pub const Diffusion: Kind = Kind(7);
    /// Covariance intersection.
    pub const Ci: Kind = Kind(8);

    /// The built-in schemes, in registry order.
    pub const BUILTIN: [Kind; 9] = [
        Kind::Independent,
        Kind::Sequeira,
        Kind::Centralized,
        Kind::CentralizedNet,
        Kind::Kcf,
        Kind::Icf,
        Kind::Hcmci,
        Kind::Diffusion,
        Kind::Ci,
    ];

    fn registration(self) -> &'static Registration {
        match BUILTIN.get(self.0 as usize) {
            Some(r) => r,
            // A kind is only made by the registry, and a registration is never removed.
            None => ADDED.read().unwrap_or_else(|e| e.into_inner())[self.0 as usize - BUILTIN.len()],
        }
    }

    /// Every registered scheme, in registry order: the built-in ones, then those a program added.
    pub fn all() -> Vec<Kind> {
        let added = ADDED.read().unwrap_or_else(|e| e.into_inner()).len();
        (0..BUILTIN.len() + added).map(|i| Kind(i as u8)).collect()
    }

    /// What `simnet estimators` says of it.
    pub fn scheme(self) -> Scheme {
        self.registration().scheme
    }

    /// Its name in topology files.
    pub fn name(self) -> &'static str {
        self.registration().scheme.name
    }

    /// The scheme called `name`.
    pub fn from_name(name: &str) -> Option<Kind> {
        if let Some(i) = BUILTIN.iter().position(|r| r.scheme.name == name) {
            return Some(Kind(i as u8));
        }
        let added = ADDED.read().unwrap_or_else(|e| e.into_inner());
        let i = added.iter().position(|r| r.scheme.name == name)?;
        Some(Kind((BUILTIN.len() + i) as u8))
    }

    /// Its byte on the wire (the `scheme` of a round's datagram).
    pub fn id(self) -> u8 {
        self.0
    }

    /// The scheme whose wire byte is `id`, if one is registered.
    pub fn from_id(id: u8) -> Option<Kind> {
        // Every received round asks: the built-in ids need no lock.
        if (id as usize) < BUILTIN.len() {
            return Some(Kind(id));
        }
        let n = BUILTIN.len() + ADDED.read().unwrap_or_else(|e| e.into_inner()).len();
        ((id as usize) < n).then_some(Kind(id))
    }

    /// Where `simnet estimators` lists the scheme called `name` (a name it does not know sorts last): the order of
    /// every table's estimator columns.
    pub fn rank(name: &str) -> usize {
        Kind::from_name(name).map_or(usize::MAX, |k| k.0 as usize)
    }

    /// `"all"` is every scheme; anything else one registered name.
    pub fn parse_list(names: &[String]) -> Result<Vec<Kind>, String> {
        let mut out = Vec::new();
        for n in names {
            let n = n.trim();
            if n == "all" {
                out.extend(Kind::all());
                continue;
            }
            match Kind::from_name(n) {
                Some(k) => out.push(k),
                None => {
                    let known: Vec<&str> = Kind::all().into_iter().map(Kind::name).collect();
                    return Err(format!("unknown estimator `{n}` (known: {}, or all)", known.join(", ")));
                }
            }
        }
        out.sort();
        out.dedup();
        Ok(out)
    }

    /// Run by the node itself over the scheme rounds (independent and sequeira are the node's two filters; the
    /// two fusion centers are the observer's).
    pub fn in_node(self) -> bool {
        matches!(self.registration().role, Role::Node(_) | Role::Configured(_))
    }

    /// A scheme a program registered, which takes its own table (`[estimators.<name>]`).
    pub fn takes_table(self) -> bool {
        matches!(self.registration().role, Role::Configured(_))
    }

    /// The scheme set up from `table`, its problems on `checks` (none for a scheme that takes no table).
    pub fn configure(self, table: &toml::Table, checks: &mut Checks) -> Option<Configured> {
        match self.registration().role {
            Role::Configured(configure) => Some(Configured {
                table: table.clone(),
                build: configure(table, checks),
            }),
            _ => None,
        }
    }

    /// One fusion center of the whole network, hosted by the observer: `centralized` and `centralized-net`.
    pub fn is_center(self) -> bool {
        matches!(self.registration().role, Role::Center)
    }
}

crate::text::by_name!(Kind, name, "estimator");

/// The schemes' parameters (`[estimators]` in a topology file).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Params {
    /// KCF's consensus gain γ in Cᵢ = γ Pᵢ / (1 + ‖Pᵢ‖); a topology's default is 1/(1 + Δ), Δ the largest
    /// degree: the step bound under which the consensus term of Olfati-Saber & Murray (2004) is stable.
    pub kcf_gamma: f64,
    /// HCMCI's measurement weight ω; `None`: the number of nodes (the paper's choice).
    pub hcmci_omega: Option<f64>,
}

impl Default for Params {
    fn default() -> Params {
        Params {
            kcf_gamma: 0.5,
            hcmci_omega: None,
        }
    }
}

/// Scheme `kind` at one node, from `initial`, with the built-in schemes' `params` or, for a scheme a program
/// registered, as `configured` set it up; `None` for a scheme no node runs itself (or one not set up).
pub fn build(
    kind: Kind,
    ctx: Context,
    initial: Gaussian,
    policy: MissingChannels,
    params: &Params,
    configured: Option<&Configured>,
) -> Option<Box<dyn Estimator>> {
    match kind.registration().role {
        Role::Node(build) => Some(build(ctx, initial, policy, params)),
        Role::Configured(_) => configured.map(|c| (c.build)(ctx, initial, policy)),
        Role::Filters | Role::Center => None,
    }
}
