//! What drivers and the observer read and take from an endpoint: its sources and neighbours, the fusion centers'
//! feed, its part of the end-of-run report.

#[allow(unused_imports)]
use super::*;

impl Endpoint {
    /// What the centralized reference needs of the last step (none unless the run holds it).
    pub fn take_feed(&mut self) -> Option<Feed> {
        self.feed.take()
    }

    /// Every distributed estimator's traffic from this node.
    pub fn scheme_traffic(&self) -> Vec<(crate::estimators::Kind, Traffic)> {
        self.schemes.traffic()
    }

    /// What its testbed's observer listens to from now on.
    pub(crate) fn listen(&mut self, listening: Listening) {
        self.listening = listening;
    }

    /// The centralized reference's feed of the step under way, for the testbed to add the truth to.
    pub(crate) fn feed_mut(&mut self) -> Option<&mut Feed> {
        self.feed.as_mut()
    }

    /// Whether it runs the networked filter.
    pub fn has_networked(&self) -> bool {
        self.filters.as_ref().is_some_and(|f| f.networked.is_some())
    }

    /// Put `stage` in front of this node (none: nothing) in place of the scenario's outsiders
    /// ([`crate::medium::Ingress`]): what it adds goes through the whole receive path ahead of what arrives, and it
    /// learns each one's fate; [`crate::Sim::set_ingress`] does it in a run. This one sends each datagram again
    /// behind the next: copies the node takes for nothing new.
    ///
    /// ```
    /// # extern crate simnet_engine as simnet;
    /// use simnet::attack::{Injection, Tally};
    /// use simnet::medium::Ingress;
    /// use simnet::time::Time;
    /// use simnet::{Overrides, Scenario, Sim};
    ///
    /// #[derive(Default)]
    /// struct Echo {
    ///     last: Option<(Option<usize>, bytes::Bytes)>,
    ///     fate: Tally,
    /// }
    ///
    /// impl Ingress for Echo {
    ///     fn on_arrival(&mut self, _t: Time, from: Option<usize>, bytes: &[u8]) -> Vec<Injection> {
    ///         let again = self.last.replace((from, bytes::Bytes::copy_from_slice(bytes)));
    ///         again.map(|(from, bytes)| Injection { attack: 0, from, bytes }).into_iter().collect()
    ///     }
    ///     fn on_step(&mut self, _t: Time, _dt: f64) -> Vec<Injection> {
    ///         Vec::new()
    ///     }
    ///     fn on_fate(&mut self, _source: usize, fate: &Tally) {
    ///         self.fate.add(fate);
    ///     }
    ///     fn tallies(&self) -> Vec<(usize, Tally)> {
    ///         vec![(0, self.fate)]
    ///     }
    /// }
    ///
    /// let scenario = Scenario::resolve("ring3")?.with(&Overrides { duration_s: Some(2.0), ..Default::default() })?;
    /// let plain = Sim::new(&scenario)?.run()?;
    /// let mut sim = Sim::new(&scenario)?;
    /// sim.set_ingress(0, Some(Box::new(Echo::default())))?;
    /// let echoed = sim.run()?;
    /// // Every copy reached the node and none was new: its estimates are those of the plain run.
    /// let (fate, arrived) = (echoed.reports[0].attacks[0].1, echoed.reports[0].counters.datagrams_in);
    /// assert_eq!(fate.sent, arrived / 2);
    /// assert_eq!((fate.used, fate.ignored), (0, fate.sent));
    /// let error = |r: simnet::RunResults| r.summary().nodes[0].networked.as_ref().unwrap().mean_error;
    /// assert_eq!(error(plain), error(echoed));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn set_ingress(&mut self, stage: Option<Box<dyn crate::medium::Ingress>>) {
        self.ingress = stage;
    }

    /// Sources whose measurements this node expects each step (node indices; own excluded).
    pub fn in_sources(&self) -> &[usize] {
        &self.in_sources
    }

    /// Neighbours in either direction (node indices).
    pub fn neighbours(&self) -> &[usize] {
        &self.session.neighbours
    }

    /// Whether every neighbour has been heard from (a hello or a measurement).
    pub fn heard_all(&self) -> bool {
        self.session.heard_all()
    }

    /// The highest step any neighbour has reported.
    pub fn max_peer_step(&self) -> Option<u64> {
        self.session.max_peer_step
    }

    /// The endpoint's figures of the run, its out-links' as `medium` carried them; the filters' figures, the trace
    /// and the IMU rows are the observer's (left empty here).
    pub(crate) fn report(&self, medium: &dyn crate::medium::Medium) -> NodeReport {
        NodeReport {
            index: self.index,
            id: self.id,
            role: self.role,
            networked: None,
            independent: None,
            schemes: Vec::new(),
            traffic: self.schemes.traffic(),
            rounds_late: self.schemes.late,
            links_out: medium.counters(self.index),
            radio: medium.radio(self.index),
            radio_links: medium.radio_links(self.index),
            rx: self.inbox.counters(),
            counters: NodeCounters {
                rejected: self.wire.rejected,
                ..self.counters
            },
            trace: Vec::new(),
            imu: Vec::new(),
            attacks: self
                .trust
                .tallies(self.ingress.as_ref().map(|i| i.tallies()).unwrap_or_default()),
        }
    }
}
