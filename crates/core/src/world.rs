//! Where every node is at every time: nodes fixed in place, and nodes mounted on a body that follows a trajectory.
//! A medium takes positions from here at the time of each transmission (distance, and later path loss, from where
//! sender and receiver are then).
//!
//! The IMU networks' nodes ride one package (the scenario's `sim.trajectory`), each at its lever arm in the body
//! frame: the world places the node's antenna there. The node's IMU still senses the package's own motion (the
//! lever arm moves no sensor reading: the IMU is at the package's origin). A linear system's nodes stand still
//! where the scenario puts them (`node[].position_m`; a random geometric graph keeps the positions it was drawn
//! from).
//!
//! ```
//! use nalgebra::Vector3;
//! use simnet_core::motion::Trajectory;
//! use simnet_core::time::Time;
//! use simnet_core::world::{Place, World};
//!
//! let mut w = World::new();
//! let package = w.add_body(Trajectory::Line);
//! w.place(Place::Fixed(Vector3::new(0.0, 5.0, 0.0)));
//! w.place(Place::Mounted { body: package, lever: Vector3::new(0.1, 0.0, 0.0) });
//! // The package moves along x at about 1 m/s: the mounted node passes the fixed one.
//! assert!((w.distance(0, 1, Time::ZERO) - (25.0f64 + 0.01).sqrt()).abs() < 0.2);
//! assert!(w.distance(0, 1, Time::from_secs(10.0)) > 10.0);
//! ```

use nalgebra::Vector3;

use crate::motion::Trajectory;
use crate::time::Time;

/// Where one node is.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Place {
    /// Still, at this position (m, in the world frame).
    Fixed(Vector3<f64>),
    /// On body `body`, at `lever` (m, in the body frame) from its origin.
    Mounted {
        /// The body, as [`World::add_body`] numbered it.
        body: usize,
        /// The lever arm in the body frame, m.
        lever: Vector3<f64>,
    },
}

/// Bodies on trajectories and the nodes placed in the world, by node index.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct World {
    bodies: Vec<Trajectory>,
    places: Vec<Place>,
}

impl World {
    /// No body, no node.
    pub fn new() -> World {
        World::default()
    }

    /// A body following `trajectory`; its number for [`Place::Mounted`].
    pub fn add_body(&mut self, trajectory: Trajectory) -> usize {
        self.bodies.push(trajectory);
        self.bodies.len() - 1
    }

    /// The next node (index [`World::len`] before the call) placed at `place`. A mount on a body the world does not
    /// have is placed at the world's origin.
    pub fn place(&mut self, place: Place) -> usize {
        self.places.push(place);
        self.places.len() - 1
    }

    /// Nodes placed.
    pub fn len(&self) -> usize {
        self.places.len()
    }

    /// No node placed.
    pub fn is_empty(&self) -> bool {
        self.places.is_empty()
    }

    /// Where node `node` is placed (`None` past the last node).
    pub fn place_of(&self, node: usize) -> Option<Place> {
        self.places.get(node).copied()
    }

    /// Node `node`'s position at time `t`: its fixed position, or its body's position with the lever arm turned
    /// by the body's attitude (p + R(θ) ℓ). The origin for a node the world does not have.
    pub fn position(&self, node: usize, t: Time) -> Vector3<f64> {
        match self.places.get(node) {
            Some(Place::Fixed(p)) => *p,
            Some(Place::Mounted { body, lever }) => match self.bodies.get(*body) {
                Some(tr) => {
                    let s = tr.at(t.as_secs());
                    s.p + crate::geom::rotation(&s.euler) * lever
                }
                None => Vector3::zeros(),
            },
            None => Vector3::zeros(),
        }
    }

    /// Whether node `node` stands still: fixed, or on a body that does not move (a node the world does not have
    /// stands at the origin).
    pub fn is_still(&self, node: usize) -> bool {
        match self.places.get(node) {
            Some(Place::Mounted { body, .. }) => self.bodies.get(*body).is_none_or(|tr| tr.is_still()),
            _ => true,
        }
    }

    /// The distance between nodes `a` and `b` at time `t`, m.
    pub fn distance(&self, a: usize, b: usize, t: Time) -> f64 {
        (self.position(a, t) - self.position(b, t)).norm()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lever arm turns with the body: on the circle (yaw along the heading), an arm along the body's x axis
    /// points along the velocity.
    #[test]
    fn a_lever_arm_turns_with_its_body() {
        let mut w = World::new();
        let b = w.add_body(Trajectory::Circle);
        w.place(Place::Mounted {
            body: b,
            lever: Vector3::zeros(),
        });
        w.place(Place::Mounted {
            body: b,
            lever: Vector3::new(0.5, 0.0, 0.0),
        });
        for t in [0.0, 1.7, 4.2, 9.9] {
            let s = Trajectory::Circle.at(t);
            let at = Time::from_secs(t);
            let arm = w.position(1, at) - w.position(0, at);
            assert!((arm.norm() - 0.5).abs() < 1e-12, "{t}");
            // Roll and pitch sway a little: the arm stays within a few degrees of the heading.
            let heading = s.v.normalize();
            assert!(arm.normalize().dot(&heading) > 0.99, "{t}: {arm:?} {heading:?}");
            assert_eq!(w.position(0, at), s.p);
        }
    }

    #[test]
    fn fixed_nodes_stay_and_unknown_ones_are_at_the_origin() {
        let mut w = World::new();
        let p = Vector3::new(3.0, 4.0, 0.0);
        w.place(Place::Fixed(p));
        w.place(Place::Mounted {
            body: 7,
            lever: Vector3::new(1.0, 0.0, 0.0),
        });
        assert_eq!(w.position(0, Time::from_secs(123.0)), p);
        assert_eq!(w.distance(0, 1, Time::ZERO), 5.0);
        assert_eq!(w.distance(0, 9, Time::ZERO), 5.0);
        assert_eq!((w.len(), w.place_of(2)), (2, None));
    }
}
