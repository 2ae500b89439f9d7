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
            attacks: self.trust.tallies(),
        }
    }
}
