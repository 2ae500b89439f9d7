//! Ranges from where each node stands: node i, at a_i in the plane, measures z_i = ‖p − a_i‖ + v, v ~ N(0, r), to a
//! body whose position p is the first two rows of the state. The observation depends on who measured ([`Site`]), so
//! every estimator linearises each node's range at that node's site, as an EKF does about the prior:
//! H_i = (p̂ − a_i)ᵀ / ‖p̂ − a_i‖ on the position rows, and z_i − (‖p̂ − a_i‖ − H_i x̂) for a linear update
//! (Bar-Shalom, Li and Kirubarajan (2001) §10.3, the range of a bearing–range sensor). A body on a site gives no
//! direction: that range carries no information (H = 0).

use std::borrow::Cow;

use nalgebra::{DMatrix, DVector};

use super::{Measurement, Sensed, Sensing, Site, Truth};
use crate::estimate::{Gaussian, Observation};
use crate::sensor::Sensor;

/// Each node's range to a body in the plane, from its site.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranges {
    sites: Vec<[f64; 2]>,
    states: usize,
    r: f64,
}

impl Ranges {
    /// Node i stands at `sites[i]` (m); the state has `states` rows, the body's position first; `r` is the range
    /// noise variance (m²). `None` unless the state holds a position and `r` is positive and finite.
    pub fn planar(sites: Vec<[f64; 2]>, states: usize, r: f64) -> Option<Ranges> {
        let finite = sites.iter().flatten().all(|v| v.is_finite());
        (states >= 2 && r > 0.0 && r.is_finite() && finite).then_some(Ranges { sites, states, r })
    }

    /// Where each node stands.
    pub fn sites(&self) -> &[[f64; 2]] {
        &self.sites
    }

    /// The range noise variance, m².
    pub fn r(&self) -> f64 {
        self.r
    }

    /// ‖p − a‖ and its gradient over the state (zero where the body stands on the site, or the node has none).
    fn range(&self, x: &DVector<f64>, site: Site) -> (f64, DMatrix<f64>) {
        let mut H = DMatrix::zeros(1, self.states);
        let Some(a) = self.sites.get(site.node) else {
            return (0.0, H);
        };
        let (dx, dy) = (x[0] - a[0], x[1] - a[1]);
        let h = dx.hypot(dy);
        if h > 0.0 {
            H[(0, 0)] = dx / h;
            H[(0, 1)] = dy / h;
        }
        (h, H)
    }
}

impl Sensing for Ranges {
    fn observation(&self) -> Observation {
        Observation {
            H: DMatrix::zeros(1, self.states),
            R: DMatrix::from_element(1, 1, self.r),
            angle_rows: vec![false],
            channel_of_row: vec![0],
        }
    }

    fn observes_alike(&self) -> bool {
        false
    }

    fn linearize_at<'a>(
        &self,
        template: &'a Observation,
        prior: &Gaussian,
        site: Site,
        z: &[&'a DVector<f64>],
    ) -> (Cow<'a, Observation>, Vec<Cow<'a, DVector<f64>>>) {
        let (h, H) = self.range(&prior.x, site);
        let offset = h - (&H * &prior.x)[0];
        let obs = Observation { H, ..template.clone() };
        (
            Cow::Owned(obs),
            z.iter().map(|z| Cow::Owned(z.add_scalar(-offset))).collect(),
        )
    }

    /// The range from the node's site to the body: a linear model's state, or the position of the motion.
    fn sense(&self, sensor: &mut Sensor, truth: &Truth, site: Site, _t: f64) -> Sensed {
        let p = match (truth.linear_state(), truth.motion_now()) {
            (Some(x), _) if x.len() >= 2 => DVector::from_vec(vec![x[0], x[1]]),
            (_, Some(m)) => DVector::from_vec(vec![m.p.x, m.p.y]),
            _ => return Sensed::default(),
        };
        if site.node >= self.sites.len() {
            return Sensed::default();
        }
        let (range, _) = self.range(&p, site);
        let v = sensor.noise(&DMatrix::from_element(1, 1, self.r.sqrt()));
        Sensed {
            z: Some(Measurement::full(v.add_scalar(range))),
            ..Sensed::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior(x: f64, y: f64) -> Gaussian {
        Gaussian {
            x: DVector::from_vec(vec![x, y, 0.5]),
            P: DMatrix::identity(3, 3),
        }
    }

    /// H is the unit vector from the site to the prior's position, on the position rows; z is moved so that the
    /// linear innovation is z − ‖p̂ − a‖.
    #[test]
    fn a_range_is_linearised_at_its_site() {
        let r = Ranges::planar(vec![[0.0, 0.0], [6.0, 0.0]], 3, 0.01).unwrap();
        let t = r.observation();
        let z = DVector::from_vec(vec![5.5]);
        for (node, (h0, h1), range) in [(0, (0.6, 0.8), 5.0), (1, (-0.6, 0.8), 5.0)] {
            let (obs, zs) = r.linearize_at(&t, &prior(3.0, 4.0), Site { node }, &[&z]);
            assert!((obs.H[(0, 0)] - h0).abs() < 1e-12 && (obs.H[(0, 1)] - h1).abs() < 1e-12 && obs.H[(0, 2)] == 0.0);
            let innovation = zs[0][0] - (&obs.H * &prior(3.0, 4.0).x)[0];
            assert!((innovation - (5.5 - range)).abs() < 1e-12, "node {node}: {innovation}");
        }
    }

    /// A body on a site gives no direction: no information; a node without a site measures nothing.
    #[test]
    fn a_range_without_a_direction_carries_nothing() {
        let r = Ranges::planar(vec![[1.0, 2.0]], 3, 0.01).unwrap();
        let t = r.observation();
        let (obs, _) = r.linearize_at(&t, &prior(1.0, 2.0), Site { node: 0 }, &[]);
        assert!(obs.H.iter().all(|v| *v == 0.0));
        let (obs, _) = r.linearize_at(&t, &prior(3.0, 2.0), Site { node: 7 }, &[]);
        assert!(obs.H.iter().all(|v| *v == 0.0));
        assert!(Ranges::planar(vec![[0.0, 0.0]], 1, 0.01).is_none());
        assert!(Ranges::planar(vec![[0.0, 0.0]], 2, 0.0).is_none());
        assert!(Ranges::planar(vec![[f64::NAN, 0.0]], 2, 0.01).is_none());
    }
}
