//! The testbed around one node: the world it senses (the truth, its IMU and sensor with their seeded noise) and
//! the observer that watches it (the [`Scorer`] and the probes). The endpoint sees only the samples the testbed
//! hands it; the truth reaches the scorer, the probes and the fusion observer, never the estimators.

use std::sync::Arc;

use nalgebra::DVector;

use super::endpoint::{Closing, Sample};
use crate::estimate::Gaussian;
use crate::model::{Model, Site, Truth};
use crate::observe::{
    Filter, ImuRecorder, LmiRecorder, MeasurementRecorder, MeasurementRow, Probes, SchemeEstimate, Scorer,
    StepEstimate, TraceRecorder, Update,
};
use crate::scenario::Scenario;
use crate::sensor::Sensor;

pub struct Testbed {
    index: usize,
    id: u32,
    topo: Arc<Scenario>,
    model: Arc<dyn Model>,
    /// The true state, advanced to the step under way.
    truth: Truth,
    /// The node's IMU and sensor, with their seeded noise (a sensing node).
    sensor: Option<Sensor>,
    /// The truth against every update: the figures of each estimator.
    pub(super) scorer: Scorer,
    pub(super) probes: Probes,
}

impl Testbed {
    /// Node `index`'s world and observer; `record_trace` keeps one row per step and filter (`trace.csv`, the plots).
    pub fn new(topo: Arc<Scenario>, index: usize, record_trace: bool) -> Testbed {
        let cfg = &topo.nodes()[index];
        let (seed, dt) = (topo.sim().seed, topo.sim().dt());
        let model = topo.model().shared();
        let sensor = cfg.role.senses().then(|| {
            Sensor::new(
                cfg.sensor.clone(),
                crate::rng::stream(seed, "sensor", index as u64, 0),
                dt,
            )
        });
        // The IMU file that replaces the simulated IMU, read at this run's steps.
        let recorded = cfg
            .recording
            .as_ref()
            .filter(|_| cfg.role.senses())
            .map(|r| Arc::new(r.data.at_steps(dt, topo.sim().steps())));
        Testbed {
            index,
            id: cfg.id,
            truth: model.truth(topo.sim().trajectory, dt, seed, recorded),
            sensor,
            scorer: Scorer::new(model.clone(), topo.sim().burn_in_steps(), topo.sim().divergence_trace),
            probes: Probes {
                trace: record_trace.then(|| TraceRecorder::new(model.clone())),
                imu: record_trace.then(ImuRecorder::default),
                measurements: record_trace.then(MeasurementRecorder::default),
                ..Default::default()
            },
            model,
            topo,
        }
    }

    /// The prior a (re)started filter begins from ([`crate::model::GroundTruth::initial`]) at step k: the truth
    /// drawn about by the node's own stream, draw number `draw`.
    pub fn prior(&self, draw: u64, k: u64) -> Gaussian {
        let k = k as usize;
        let first = self.truth.recording().and_then(|(rec, _)| {
            let mag = rec.mag.as_ref().and_then(|v| v.get(k));
            rec.imu.get(k).map(|s| (s, mag))
        });
        let mut rng = crate::rng::stream(self.topo.sim().seed, "init", self.index as u64, draw);
        self.model.initial(&self.truth.state(&*self.model), first, &mut rng)
    }

    /// The world moves on to step k; the shift of coordinates the estimates take with it (a linear model's rebase).
    pub fn advance_to(&mut self, k: u64) -> Option<DVector<f64>> {
        self.truth.advance_to(k);
        self.truth.take_shift()
    }

    /// What the node senses at step k ([`crate::model::Sensing::sense`]), recorded by the probes.
    pub fn sense(&mut self, k: u64) -> Sample {
        let Some(sensor) = self.sensor.as_mut() else {
            return Sample::default();
        };
        let t = k as f64 * self.topo.sim().dt();
        let sensed = self.model.sense(sensor, &self.truth, Site { node: self.index }, t);
        if let Some(row) = &sensed.row {
            self.probes.each().for_each(|p| p.on_imu(row));
        }
        if let (Some(m), false) = (&sensed.z, self.probes.is_empty()) {
            let rows: Vec<usize> = (0..m.z.len()).filter(|&r| m.present[r]).collect();
            let row = MeasurementRow {
                step: k,
                node: self.id,
                values: rows.iter().map(|&r| m.z[r]).collect(),
                rows,
            };
            self.probes.each().for_each(|p| p.on_measurement(&row));
        }
        Sample {
            imu: sensed.imu,
            own: sensed.z,
            ..Sample::default()
        }
    }

    /// The true state of the step under way, in the model's coordinates.
    pub fn truth(&self) -> DVector<f64> {
        self.truth.state(&*self.model)
    }

    /// Step k closed: each update scored against the truth and handed to the probes, in order; the step's
    /// estimates for the fusion observer.
    pub fn observe(&mut self, k: u64, closing: Closing) -> StepEstimate {
        let Closing {
            lmi,
            updates,
            networked,
            filters,
        } = closing;
        if let Some(step) = &lmi {
            self.probes.each().for_each(|p| p.on_lmi(step));
        }
        let truth = self.truth();
        let t = k as f64 * self.topo.sim().dt();
        let mut schemes = Vec::new();
        for up in updates {
            let u = Update {
                node: self.id,
                step: k,
                t,
                filter: up.filter,
                truth: &truth,
                prior: &up.prior,
                post: &up.post,
                failed: up.failed,
                feasible: up.feasible,
                received: &up.received,
            };
            let score = self.scorer.score(&u);
            self.probes.each().for_each(|p| p.on_update(&u, &score));
            if let Filter::Scheme(kind) = up.filter {
                schemes.push(SchemeEstimate {
                    kind,
                    x: up.post.x,
                    P: Some(up.post.P),
                });
            }
        }
        schemes.extend(filters);
        StepEstimate {
            node: self.index,
            step: k,
            truth,
            frame: self.truth.frame(),
            networked,
            diverged: self.scorer.metrics(Filter::Networked).diverged,
            schemes,
        }
    }

    /// Keep the LMI terms of every networked update from now on (for a protocol search).
    pub fn record_lmi(&mut self) {
        self.probes.lmi.get_or_insert_with(LmiRecorder::default);
    }
}
