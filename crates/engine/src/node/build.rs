//! A node built from its scenario: its filters, links, streams and schemes, and the prior a (re)started filter
//! begins from.

#[allow(unused_imports)]
use super::*;

impl Node {
    /// `record_trace` keeps one row per step and filter (needed for `trace.csv` and the plots).
    pub fn new(topo: Arc<Scenario>, index: usize, record_trace: bool) -> Node {
        let cfg = &topo.nodes()[index];
        let seed = topo.sim().seed;
        let dt = topo.sim().dt();
        let model = topo.model().shared();
        let Q = model.process_noise(cfg.role.senses().then_some(&cfg.sensor), dt);
        let obs = model.observation();
        let policy = MissingChannels::for_noise(&obs.R, topo.consensus().inflation);
        let sensor = cfg.role.senses().then(|| {
            Sensor::new(
                cfg.sensor.clone(),
                crate::rng::stream(seed, "sensor", index as u64, 0),
                dt,
            )
        });
        let in_node = topo.estimators().any_in_node();
        // The IMU file that replaces the simulated IMU, read at this run's steps.
        let recorded = cfg
            .recording
            .as_ref()
            .filter(|_| cfg.role.senses())
            .map(|r| Arc::new(r.data.at_steps(dt, topo.sim().steps())));
        let truth = model.truth(topo.sim().trajectory, dt, seed, recorded);
        let obs_dim = obs.dim();
        let trust = trust::Trust::new(&topo, index, obs_dim);
        let mut node = Node {
            index,
            id: cfg.id,
            role: cfg.role,
            truth,
            sensor,
            Q,
            obs,
            policy,
            filters: None,
            initial: Gaussian {
                x: DVector::zeros(1),
                P: DMatrix::identity(1, 1),
            },
            last_imu: None,
            outs: topo.out_links(index).map(|l| l.to).collect(),
            outbox: Default::default(),
            wire: Wire::new(topo.nodes()[index].id, topo.security().key.as_ref(), 0),
            up: true,
            restarting: false,
            inbox: Inbox::new(topo.in_links(index).map(|l| l.from), obs_dim),
            counters: NodeCounters::default(),
            scorer: Scorer::new(model.clone(), topo.sim().burn_in_steps(), topo.sim().divergence_trace),
            probes: Probes {
                trace: record_trace.then(|| TraceRecorder::new(model.clone())),
                imu: record_trace.then(ImuRecorder::default),
                measurements: record_trace.then(MeasurementRecorder::default),
                ..Default::default()
            },
            model,
            started: false,
            session: Session::new(&topo, index),
            in_sources: topo
                .in_links(index)
                .map(|l| l.from)
                .filter(|&j| topo.nodes()[j].role.senses())
                .collect(),
            schemes: Schemes::new(Vec::new(), 1),
            feed: None,
            star_sink: topo.estimators().sink == Some(index)
                && topo.estimators().run.contains(&crate::estimators::Kind::CentralizedNet),
            last_step: None,
            run: u64::MAX,
            booted: 0,
            handshake: false,
            hello_due: false,
            trust,
            ingress: topo.ingress(index),
            topo,
            due: super::clock::Due::Step(0),
        };
        node.initial = node.initial_estimate(0, 0);
        node.filters = node
            .role
            .estimates()
            .then(|| Filters::new(&node.topo, index, &node.initial, node.policy));
        if in_node {
            let ctx = schemes::context(&node.topo, index, &*node.model);
            let e = node.topo.estimators();
            let slots = e
                .run
                .iter()
                .filter(|k| k.in_node())
                .filter_map(|&k| {
                    let configured = e.configured.get(&k);
                    crate::estimators::build(k, ctx.clone(), node.initial.clone(), node.policy, &e.params, configured)
                        .map(|est| (k, est))
                })
                .collect();
            node.schemes = Schemes::new(slots, e.rounds);
        }
        node
    }

    /// The prior a (re)started filter begins from ([`crate::model::GroundTruth::initial`]), from the node's own stream.
    pub(super) fn initial_estimate(&self, restart: u64, k: u64) -> Gaussian {
        let k = k as usize;
        let first = self.truth.recording().and_then(|(rec, _)| {
            let mag = rec.mag.as_ref().and_then(|v| v.get(k));
            rec.imu.get(k).map(|s| (s, mag))
        });
        let mut rng = crate::rng::stream(self.topo.sim().seed, "init", self.index as u64, restart);
        self.model.initial(&self.truth.state(&*self.model), first, &mut rng)
    }
}
