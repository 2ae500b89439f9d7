//! A node's two filters fed by the same IMU, both [`crate::estimators::Estimator`]s: the networked one
//! ([`Sequeira`]: consensus over whatever arrived, LMI-guarded) and the independent twin that uses only the node's
//! own measurement ([`Local`]), the baseline of Sequeira (2023). The node drives them as it drives every scheme
//! (predict, reset, finish at the step's deadline); it scores them as `networked` and `independent`. A model whose
//! nodes observe differently ([`crate::model::Sensing::observes_alike`]) has no networked filter: Sequeira's eqs.
//! (5)–(10) form one gain from one h for every source.

use crate::estimate::{Gaussian, MissingChannels};
use crate::estimators::{Local, Sequeira, SequeiraParams};
use crate::scenario::Scenario;

/// The filters of an estimating node.
#[derive(Clone)]
pub(super) struct Filters {
    /// None where the model's nodes observe differently.
    pub networked: Option<Sequeira>,
    pub independent: Local,
}

impl Filters {
    /// Node `index`'s filters from `initial`, with its row of the scenario's β.
    pub fn new(topo: &Scenario, index: usize, initial: &Gaussian, policy: MissingChannels) -> Filters {
        let c = topo.consensus();
        let params = SequeiraParams {
            index,
            beta0: c.beta0,
            beta: c.beta.row(index).to_vec(),
            alpha: c.lmi.alpha,
            gamma: c.lmi.gamma,
            guard: c.lmi.enabled,
            policy,
        };
        Filters {
            networked: topo
                .model()
                .get()
                .observes_alike()
                .then(|| Sequeira::new(initial.clone(), params)),
            independent: Local::new(initial.clone(), policy),
        }
    }
}
