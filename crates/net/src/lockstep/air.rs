//! A medium that cannot be split by sender ([`simnet_engine::scenario::MediumConfig::Radio`]), shared by every
//! worker: one place decides the fate of every frame on the air, while the datagrams it delivers still travel
//! between the nodes' own sockets. Each window, every worker hands the medium its nodes' transmissions and marks the
//! window posted ([`Pace::posted`]); a worker asks the medium for the window's deliveries only once every worker has
//! posted it, as [`simnet_engine::Sim`] does in memory, so the same seed gives the same figures.

use std::sync::{Arc, Mutex, MutexGuard};

use simnet_engine::link::{FaultSchedule, LinkCounters};
use simnet_engine::medium::{Delivery, Medium, Transmission};
use simnet_engine::time::Time;

/// The whole medium behind a lock, one handle per node.
#[derive(Debug, Clone)]
pub(super) struct Air(Arc<Mutex<Box<dyn Medium>>>);

impl Air {
    pub(super) fn new(medium: Box<dyn Medium>) -> Air {
        Air(Arc::new(Mutex::new(medium)))
    }

    /// A worker that panicked while holding the lock leaves the medium as it was between two calls: still usable.
    fn get(&self) -> MutexGuard<'_, Box<dyn Medium>> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl Medium for Air {
    fn transmit(&mut self, from: usize, tx: Transmission, faults: &FaultSchedule) {
        self.get().transmit(from, tx, faults)
    }
    fn poll_delivery(&mut self, from: usize, now: Time) -> Option<Delivery> {
        self.get().poll_delivery(from, now)
    }
    fn poll_timeout(&self, from: usize) -> Option<Time> {
        self.get().poll_timeout(from)
    }
    fn counters(&self, from: usize) -> Vec<(usize, LinkCounters)> {
        self.get().counters(from)
    }
    fn radio(&self, node: usize) -> Option<simnet_engine::medium::radio::RadioCounters> {
        self.get().radio(node)
    }
    fn radio_links(&self, from: usize) -> Vec<(usize, simnet_engine::medium::radio::LinkQuality)> {
        self.get().radio_links(from)
    }
}
