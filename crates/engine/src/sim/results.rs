//! What a run gives back, whichever transport drove it.

use std::sync::Arc;

use crate::node::{LmiStep, NodeReport};
use crate::observe::fusion::Observer;
pub use crate::report::summary::Clock;
use crate::report::summary::{Schedule, Summary};
use crate::report::trace::TraceWriter;
use crate::scenario::Scenario;

pub struct RunResults {
    pub scenario: Arc<Scenario>,
    pub clock: Clock,
    pub reports: Vec<NodeReport>,
    /// The fusion of the nodes' estimates (none when the run was asked not to fuse).
    pub observer: Option<Observer>,
    pub steps_done: u64,
    pub interrupted: bool,
    /// Wall-clock seconds the run took, where its driver measured them (0 for [`super::Sim`], which reads no
    /// clock).
    pub wall_s: f64,
    /// Frames of the virtual clock over sockets that never came out of a socket in time (each carries what one link
    /// delivered in one step).
    pub socket_losses: u64,
    /// Frames of the virtual clock sent again because a receiver asked for them (the kernel had dropped them).
    pub frames_resent: u64,
    /// The recorder the run was given, handed back with every row given to it.
    pub trace: Option<TraceWriter>,
    /// Each node's per-step LMI terms, when they were asked for.
    pub lmi: Vec<Vec<LmiStep>>,
    /// How far a wall-clock run fell behind its schedule (none on the virtual clock).
    pub schedule: Option<Schedule>,
}

impl RunResults {
    /// The run's summary (`summary.json`, the table).
    pub fn summary(&self) -> Summary {
        let mut s = Summary::build(
            &self.scenario,
            self.clock,
            &self.reports,
            self.observer.as_ref().and_then(Observer::summary),
            self.steps_done,
            self.interrupted,
            self.wall_s,
            self.socket_losses,
        );
        s.transport.schedule = self.schedule;
        s.transport.frames_resent = self.frames_resent;
        s.estimators = crate::report::summary::EstimatorSummary::of_run(
            &self.scenario,
            &self.reports,
            self.observer.as_ref().and_then(Observer::schemes),
        );
        s
    }

    /// [`RunResults::summary`], and for an attacked run each node's error beside the same seed's clean run (in
    /// memory: the virtual clock's results are the same over UDP), as `simnet run` prints it.
    pub fn summary_beside_clean(&self) -> Result<Summary, super::SimError> {
        let mut s = self.summary();
        if !self.scenario.attacks().is_empty() && !s.interrupted {
            let clean = super::Sim::new(&self.scenario.without_attacks())?.run()?.summary();
            s.compare_clean(&clean);
        }
        Ok(s)
    }
}
