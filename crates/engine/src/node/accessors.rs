//! What drivers and the observer read and take from a node: its sources and neighbours, the rows it recorded, the
//! fusion centers' feed, its end-of-run report.

#[allow(unused_imports)]
use super::*;

impl Node {
    /// What the centralized reference needs of the last step (none unless the run holds it).
    pub fn take_feed(&mut self) -> Option<Feed> {
        self.feed.take()
    }

    /// Every distributed estimator's traffic from this node.
    pub fn scheme_traffic(&self) -> Vec<(crate::estimators::Kind, Traffic)> {
        self.schemes.traffic()
    }

    /// Keep the LMI terms of every networked update from now on (for a protocol search; costs one extra
    /// gain computation per step).
    pub fn record_lmi(&mut self) {
        self.probes.lmi.get_or_insert_with(LmiRecorder::default);
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

    /// Feed `p` every update, IMU sample and set of LMI terms from now on.
    pub fn add_probe(&mut self, p: Box<dyn Probe>) {
        self.probes.added.push(p);
    }

    pub fn take_lmi_log(&mut self) -> Vec<LmiStep> {
        self.probes.lmi.as_mut().map(LmiRecorder::take).unwrap_or_default()
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

    /// The node's own measurements recorded since the last call.
    pub fn take_measurements(&mut self) -> Vec<MeasurementRow> {
        self.probes
            .measurements
            .as_mut()
            .map(MeasurementRecorder::take)
            .unwrap_or_default()
    }

    /// The IMU rows recorded since the last call.
    pub fn take_imu(&mut self) -> Vec<ImuRow> {
        self.probes.imu.as_mut().map(ImuRecorder::take).unwrap_or_default()
    }

    /// The trace rows recorded since the last call (a shell streams them out step by step).
    pub fn take_trace(&mut self) -> Vec<TraceRow> {
        self.probes.trace.as_mut().map(TraceRecorder::take).unwrap_or_default()
    }

    /// The node's figures of the run, its out-links' as `medium` carried them.
    pub fn report(&mut self, medium: &dyn crate::medium::Medium) -> NodeReport {
        let est = self.role.estimates();
        NodeReport {
            index: self.index,
            id: self.id,
            role: self.role,
            networked: self
                .filters
                .as_ref()
                .is_some_and(|f| f.networked.is_some())
                .then(|| self.scorer.metrics(Filter::Networked).clone()),
            independent: est.then(|| self.scorer.metrics(Filter::Independent).clone()),
            schemes: if est {
                self.scorer.scheme_metrics().to_vec()
            } else {
                Vec::new()
            },
            traffic: self.schemes.traffic(),
            rounds_late: self.schemes.late,
            links_out: medium.counters(self.index),
            rx: self.inbox.counters(),
            counters: NodeCounters {
                rejected: self.wire.rejected,
                ..self.counters
            },
            trace: self.take_trace(),
            imu: self.take_imu(),
            attacks: self
                .trust
                .tallies(self.ingress.as_ref().map(|i| i.tallies()).unwrap_or_default()),
        }
    }
}
