//! An endpoint built from its scenario: its filters, links, streams and schemes, from the prior its testbed drew.

#[allow(unused_imports)]
use super::*;

impl Endpoint {
    /// Node `index` of `topo`, its filters starting from `initial`.
    pub(crate) fn new(topo: Arc<Scenario>, index: usize, initial: Gaussian) -> Endpoint {
        let cfg = &topo.nodes()[index];
        let dt = topo.sim().dt();
        let model = topo.model().shared();
        let Q = model.process_noise(cfg.role.senses().then_some(&cfg.sensor), dt);
        let obs = model.observation();
        let policy = MissingChannels::for_noise(&obs.R, topo.consensus().inflation);
        let in_node = topo.estimators().any_in_node();
        let obs_dim = obs.dim();
        let trust = trust::Trust::new(&topo, index, obs_dim);
        let mut node = Endpoint {
            index,
            id: cfg.id,
            role: cfg.role,
            Q,
            obs,
            policy,
            filters: None,
            initial,
            last_imu: None,
            outs: topo.out_links(index).map(|l| l.to).collect(),
            outbox: Default::default(),
            wire: Wire::new(topo.nodes()[index].id, topo.security().key.as_ref(), 0),
            up: true,
            restarting: false,
            inbox: Inbox::new(topo.in_links(index).map(|l| l.from), obs_dim),
            counters: NodeCounters::default(),
            listening: Listening::default(),
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
            due: Due::Step(0),
        };
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
}
