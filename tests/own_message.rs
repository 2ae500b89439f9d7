//! A registered scheme that writes its own message bytes ([`Message::Own`]): each node sends its estimate as 32-bit
//! floats and averages its neighbours' with Metropolis weights before its own Kalman update. The bytes cross real
//! sockets unchanged (the same figures over UDP as in memory), and each message is exactly as long as its body says
//! (against `ci`, which sends x and P as 64-bit floats, over the same links and headers).
//!
//! A test binary of its own: registering a scheme changes every later run of the process (`all` names it).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use bytes::Bytes;
use nalgebra::DVector;
use simnet::estimate::{EstimateError, Gaussian, MissingChannels};
use simnet::estimators::{register, Context, Estimator, Kind, Message, Scheme, StepInput};
use simnet::net::RunOptions;
use simnet::wire::Body;
use simnet::{Overrides, Scenario, Sim};

/// The state dimension the scheme was built with.
static STATES: AtomicUsize = AtomicUsize::new(0);

struct F32 {
    g: Gaussian,
    ctx: Context,
    policy: MissingChannels,
}

fn encode(x: &DVector<f64>) -> Bytes {
    x.iter()
        .flat_map(|v| (*v as f32).to_le_bytes())
        .collect::<Vec<u8>>()
        .into()
}

fn decode(b: &[u8], n: usize) -> Result<DVector<f64>, EstimateError> {
    if b.len() != 4 * n {
        return Err(EstimateError::Dimension {
            what: format!("{} bytes for {n} states", b.len()),
        });
    }
    let v = b
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64);
    Ok(DVector::from_iterator(n, v))
}

impl Estimator for F32 {
    fn name(&self) -> &'static str {
        "f32"
    }
    fn state(&self) -> Option<&Gaussian> {
        Some(&self.g)
    }
    fn state_mut(&mut self) -> Option<&mut Gaussian> {
        Some(&mut self.g)
    }
    fn message(&self, _round: usize) -> Option<Message> {
        Some(Message::Own(encode(&self.g.x)))
    }
    fn combine(&mut self, _: usize, arrived: &[(usize, &Message)], _: &StepInput<'_>) -> Result<(), EstimateError> {
        let n = self.g.x.len();
        let (mut sum, mut total) = (&self.g.x * self.ctx.self_weight, self.ctx.self_weight);
        for (j, m) in arrived {
            let Message::Own(bytes) = m else { continue };
            let w = self.ctx.weights.iter().find(|(k, _)| k == j).map_or(0.0, |(_, w)| *w);
            sum += decode(bytes, n)? * w;
            total += w;
        }
        self.g.x = sum / total;
        Ok(())
    }
    fn finish(&mut self, input: &StepInput<'_>) -> Result<(), EstimateError> {
        if let Some(m) = input.own {
            self.g = input.update(&self.g, input.node, m, self.policy)?;
        }
        Ok(())
    }
}

#[test]
fn a_schemes_own_bytes_cross_the_sockets_and_cost_what_they_hold() {
    let scheme = Scheme {
        name: "f32",
        reference: "a test: estimates averaged in 32-bit floats",
        messages: "every round: x as 32-bit floats",
        parameters: "-",
    };
    let f32_kind = register(scheme, |_, _| {
        Arc::new(|ctx, g, policy| {
            STATES.store(g.x.len(), Ordering::Relaxed);
            Box::new(F32 { g, ctx, policy })
        })
    })
    .unwrap();
    let with = |kind: Kind| {
        Scenario::resolve("ring3")
            .unwrap()
            .with(&Overrides {
                duration_s: Some(3.0),
                loss: Some(simnet::link::LossModel::Bernoulli { p: 0.1 }),
                estimators: Some(vec![kind]),
                ..Default::default()
            })
            .unwrap()
    };
    let scenario = with(f32_kind);
    let memory = Sim::new(&scenario).unwrap().run().unwrap().summary();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let udp = rt
        .block_on(simnet::net::run(
            Arc::new(scenario.clone()),
            RunOptions::default(),
            std::future::pending(),
        ))
        .unwrap()
        .summary();
    let (m, u) = (&memory.estimators["f32"], &udp.estimators["f32"]);
    assert!(m.messages > 0);
    assert_eq!((m.messages, m.bytes), (u.messages, u.bytes));
    for (a, b) in m.nodes.iter().zip(&u.nodes) {
        let (a, b) = (a.figures.mean_error.unwrap(), b.figures.mean_error.unwrap());
        assert!((a - b).abs() <= 1e-9 * a, "node error {a} in memory, {b} over UDP");
    }

    // The same links and headers carrying ci's x and P (64-bit floats, P as its upper triangle): the difference
    // in bytes is the difference of the bodies, message by message.
    let ci = Sim::new(&with(Kind::Ci)).unwrap().run().unwrap().summary();
    let ci = &ci.estimators["ci"];
    assert_eq!(ci.messages, m.messages);
    let n = STATES.load(Ordering::Relaxed);
    let len = |b: &Body| postcard::to_allocvec(b).unwrap().len() as u64;
    let estimate = Body::Estimate {
        n: n as u8,
        x: vec![0.5; n],
        sym: vec![0.5; n * (n + 1) / 2],
    };
    let own = Body::Own(vec![0; 4 * n]);
    assert_eq!(
        ci.bytes - m.bytes,
        m.messages * (len(&estimate) - len(&own)),
        "{n} states"
    );
}
