//! The schemes a run can hold, by name: [`Kind`] (its index is the `scheme` byte of a round's datagram),
//! [`Params`], [`build`] for the schemes a node runs itself, and the wire form of a [`Message`].

use nalgebra::{DMatrix, DVector};

use super::{Ci, Context, Diffusion, Estimator, Hcmci, Icf, Info, Kcf, Message};
use crate::estimate::{Gaussian, MissingChannels};
use crate::model::Measurement;
use crate::wire::Body;

/// Every scheme, in the order of [`super::SCHEMES`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// The node's own filter, nothing exchanged.
    Independent,
    /// The β-weighted consensus of Sequeira (2023).
    Sequeira,
    /// The centralized filter over every measurement, delivered whole.
    Centralized,
    /// The centralized filter at a sink, over the lossy links.
    CentralizedNet,
    /// The Kalman consensus filter.
    Kcf,
    /// The information consensus filter.
    Icf,
    /// Hybrid consensus on measurements and information.
    Hcmci,
    /// Diffusion Kalman filtering.
    Diffusion,
    /// Covariance intersection.
    Ci,
}

impl Kind {
    /// Every scheme, in registry order.
    pub const ALL: [Kind; 9] = [
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

    /// Its name in topology files.
    pub fn name(self) -> &'static str {
        super::SCHEMES[self as usize].name
    }

    /// The scheme called `name`.
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Where `simnet estimators` lists the scheme called `name` (a name it does not know sorts last): the order of
    /// every table's estimator columns.
    pub fn rank(name: &str) -> usize {
        Kind::from_name(name).map_or(usize::MAX, |k| k as usize)
    }

    /// `"all"` is every scheme; anything else one name of [`Kind::ALL`].
    pub fn parse_list(names: &[String]) -> Result<Vec<Kind>, String> {
        let mut out = Vec::new();
        for n in names {
            let n = n.trim();
            if n == "all" {
                out.extend(Kind::ALL);
                continue;
            }
            match Kind::from_name(n) {
                Some(k) => out.push(k),
                None => {
                    let known: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
                    return Err(format!("unknown estimator `{n}` (known: {}, or all)", known.join(", ")));
                }
            }
        }
        out.sort();
        out.dedup();
        Ok(out)
    }

    /// The scheme at `i` in [`Kind::ALL`].
    pub fn from_index(i: u8) -> Option<Kind> {
        Kind::ALL.get(i as usize).copied()
    }

    /// Run by the node itself over the scheme rounds (independent and sequeira are the node's two filters; the
    /// two fusion centers are the observer's).
    pub fn in_node(self) -> bool {
        !matches!(self, Kind::Independent | Kind::Sequeira) && !self.is_center()
    }

    /// One fusion center of the whole network, hosted by the observer: `centralized` and `centralized-net`.
    pub fn is_center(self) -> bool {
        matches!(self, Kind::Centralized | Kind::CentralizedNet)
    }
}

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

/// Scheme `kind` at one node, from `initial`; `None` for a scheme no node runs itself.
pub fn build(
    kind: Kind,
    ctx: Context,
    initial: Gaussian,
    policy: MissingChannels,
    params: &Params,
) -> Option<Box<dyn Estimator>> {
    let nodes = ctx.nodes as f64;
    Some(match kind {
        Kind::Kcf => Box::new(Kcf::new(ctx, initial, policy, params.kcf_gamma)),
        Kind::Icf => Box::new(Icf::new(ctx, initial)),
        Kind::Hcmci => Box::new(Hcmci::new(ctx, initial, params.hcmci_omega.unwrap_or(nodes))),
        Kind::Diffusion => Box::new(Diffusion::new(ctx, initial, policy, true, true)),
        Kind::Ci => Box::new(Ci::new(ctx, initial, policy)),
        Kind::Independent | Kind::Sequeira | Kind::Centralized | Kind::CentralizedNet => return None,
    })
}

fn upper(M: &DMatrix<f64>) -> Vec<f64> {
    let n = M.nrows();
    let mut v = Vec::with_capacity(n * (n + 1) / 2);
    for r in 0..n {
        for c in r..n {
            // The mean of both triangles: what a symmetric matrix off by rounding most likely was.
            v.push(0.5 * (M[(r, c)] + M[(c, r)]));
        }
    }
    v
}

fn symmetric(n: usize, v: &[f64]) -> DMatrix<f64> {
    let mut M = DMatrix::zeros(n, n);
    let mut it = v.iter();
    for r in 0..n {
        for c in r..n {
            let x = *it.next().unwrap_or(&0.0);
            M[(r, c)] = x;
            M[(c, r)] = x;
        }
    }
    M
}

/// Why a round's message cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MessageError {
    #[error("a message of {got} states, the model has {want}")]
    /// A message with another state dimension.
    States {
        /// The message's.
        got: usize,
        /// The model's.
        want: usize,
    },
    /// A measurement row past the model's rows.
    #[error("a measurement with rows beyond the model's {0}")]
    Rows(usize),
    /// A state too large for a datagram.
    #[error("a state of {0} rows cannot travel (at most {max})", max = crate::wire::MAX_STATES)]
    TooLarge(usize),
}

/// The wire form of `m`.
pub fn to_body(m: &Message) -> Result<Body, MessageError> {
    let n_of = |n: usize| u8::try_from(n).ok().filter(|n| *n as usize <= crate::wire::MAX_STATES);
    Ok(match m {
        Message::Measurement(m) => {
            let rows = (0..m.z.len().min(64))
                .filter(|&r| m.present[r])
                .fold(0u64, |acc, r| acc | 1 << r);
            Body::Measurement {
                rows,
                values: (0..m.z.len().min(64))
                    .filter(|&r| m.present[r])
                    .map(|r| m.z[r])
                    .collect(),
            }
        }
        Message::Information(i) => Body::Information {
            n: n_of(i.y.len()).ok_or(MessageError::TooLarge(i.y.len()))?,
            sym: upper(&i.Y),
            vec: i.y.iter().copied().collect(),
        },
        Message::Hybrid { prior, measurement } => Body::Hybrid {
            n: n_of(prior.y.len()).ok_or(MessageError::TooLarge(prior.y.len()))?,
            prior: (upper(&prior.Y), prior.y.iter().copied().collect()),
            measurement: (upper(&measurement.Y), measurement.y.iter().copied().collect()),
        },
        Message::Estimate(g) => Body::Estimate {
            n: n_of(g.x.len()).ok_or(MessageError::TooLarge(g.x.len()))?,
            x: g.x.iter().copied().collect(),
            sym: upper(&g.P),
        },
    })
}

/// The message a checked [`Body`] carries, for a model of `states` states and `rows` measurement rows.
pub fn from_body(b: &Body, states: usize, rows: usize) -> Result<Message, MessageError> {
    let dim = |n: u8| {
        if n as usize == states {
            Ok(states)
        } else {
            Err(MessageError::States {
                got: n as usize,
                want: states,
            })
        }
    };
    let info = |n: usize, Y: &[f64], y: &[f64]| Info {
        Y: symmetric(n, Y),
        y: DVector::from_column_slice(y),
    };
    Ok(match b {
        Body::Measurement { rows: mask, values } => {
            if rows < 64 && mask >> rows != 0 {
                return Err(MessageError::Rows(rows));
            }
            let mut m = Measurement::empty(rows);
            m.merge(*mask, values);
            Message::Measurement(m)
        }
        Body::Information { n, sym, vec } => {
            let n = dim(*n)?;
            Message::Information(info(n, sym, vec))
        }
        Body::Hybrid { n, prior, measurement } => {
            let n = dim(*n)?;
            Message::Hybrid {
                prior: info(n, &prior.0, &prior.1),
                measurement: info(n, &measurement.0, &measurement.1),
            }
        }
        Body::Estimate { n, x, sym } => {
            let n = dim(*n)?;
            Message::Estimate(Gaussian {
                x: DVector::from_column_slice(x),
                P: symmetric(n, sym),
            })
        }
    })
}
