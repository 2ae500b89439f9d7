//! A node's two filters fed by the same IMU — the networked one (consensus over whatever arrived, LMI-guarded) and
//! the independent twin that uses only the node's own measurement, the baseline of Sequeira (2023) — and one step's
//! update of both over any [`Model`].

use nalgebra::DVector;

use crate::estimate::{
    guarded_update, kalman_update, EstimateError, Gaussian, LmiTerms, MissingChannels, Observation, Source,
};
use crate::model::{Measurement, Model};
use crate::scenario::{weight_in, ConsensusConfig};

/// The filters of an estimating node.
#[derive(Debug, Clone)]
pub(super) struct Filters {
    pub networked: Gaussian,
    pub independent: Gaussian,
}

/// What one node's update needs besides the data.
pub(super) struct Inputs<'a> {
    pub model: &'a dyn Model,
    pub obs: &'a Observation,
    pub policy: MissingChannels,
    pub consensus: &'a ConsensusConfig,
    /// This node's row of β: non-zero (source, weight), by source.
    pub beta: &'a [(usize, f64)],
    pub index: usize,
    pub k: u64,
}

pub(super) struct Updated {
    pub networked: Result<Gaussian, EstimateError>,
    pub independent: Result<Gaussian, EstimateError>,
    /// (17) and (19) held for the networked update.
    pub feasible: bool,
    /// The β-independent LMI terms of the networked update, when asked for.
    pub lmi: Option<Result<Option<LmiTerms>, EstimateError>>,
}

/// Both filters' updates with `used` (node index, measurement), sorted by source so that sums are deterministic.
pub(super) fn update(inp: &Inputs<'_>, priors: &Filters, used: &[(usize, &Measurement)], want_lmi: bool) -> Updated {
    let (c, beta, k) = (inp.consensus, inp.beta, inp.k);
    // Each filter sees the observation about its own prior (linearised for the attitude EKF).
    let zs: Vec<&DVector<f64>> = used.iter().map(|(_, p)| &p.z).collect();
    let (obs_net, z_net) = inp.model.linearize_at(inp.obs, &priors.networked, &zs);
    let own_at = used.iter().position(|(s, _)| *s == inp.index);
    let sources: Vec<Source<'_>> = used
        .iter()
        .zip(&z_net)
        .filter(|((s, _), _)| weight_in(beta, *s) > 0.0)
        .map(|((s, p), z)| Source {
            beta: weight_in(beta, *s),
            z,
            present: &p.present,
        })
        .collect();
    // The independent update this step if (17)/(19) fail: own measurement, else the highest-weight source.
    let own = own_at.map(|i| Source {
        beta: 1.0,
        z: &z_net[i],
        present: &used[i].1.present,
    });
    let fallback = own.or_else(|| sources.iter().max_by(|a, b| a.beta.total_cmp(&b.beta)).cloned());
    let lmi = want_lmi.then(|| {
        // Every source that arrived, whatever its β, so that a search may weigh it.
        let data: Vec<(&DVector<f64>, &[bool])> = used
            .iter()
            .zip(&z_net)
            .map(|((_, p), z)| (z.as_ref(), &p.present[..]))
            .collect();
        LmiTerms::new(
            &priors.networked,
            &obs_net,
            c.beta0,
            &data,
            inp.policy,
            k,
            c.lmi.alpha,
            c.lmi.gamma,
        )
    });
    let guard = c.lmi.enabled.then_some((c.lmi.alpha, c.lmi.gamma));
    let (networked, feasible) = guarded_update(
        &priors.networked,
        &obs_net,
        c.beta0,
        &sources,
        fallback.as_ref(),
        inp.policy,
        k,
        guard,
    );
    let independent = match own_at {
        Some(i) => {
            let mine = used[i].1;
            let (obs, z) = inp.model.linearize_at(inp.obs, &priors.independent, &[&mine.z]);
            kalman_update(&priors.independent, &obs, &z[0], &mine.present, inp.policy)
        }
        None => Ok(priors.independent.clone()),
    };
    let normalised = |r: Result<Gaussian, EstimateError>| {
        r.map(|mut g| {
            inp.model.normalize(&mut g);
            g
        })
    };
    Updated {
        networked: normalised(networked),
        independent: normalised(independent),
        feasible,
        lmi,
    }
}
