//! README's table of attacks on the wire, measured against real node processes: ring3 as three `simnet node`
//! processes on loopback for 5 s, node 0 talking to nodes 1 and 2 through relays of the test (as a NAT would), which
//! attack node 1. Each attack runs three ways: the network sealed and the attacker without the key, the attacker
//! holding the key (an insider), and the network `--insecure`. The table is printed; what the key must guarantee is
//! asserted, and what it cannot (an insider) is reported as it is.
//!
//! `cargo test --test integration wire_attack_table -- --ignored --nocapture` (about two minutes; `.ci/run` runs it
//! alone, after the long suite). The table is also written to `target/tmp/wire-attack-table.md`.

use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use simnet::time::Time;
use simnet::wire::secure::{claimed, Key, Opener, Sealer};
use simnet::wire::{peek_header, Datagram, Header, Payload, KIND_MEASUREMENT};

const DURATION_S: f64 = 5.0;
const STEPS: u64 = 500;

#[derive(Clone, Copy, PartialEq, Debug)]
enum Mode {
    /// Sealed; the attacker has no key.
    Outsider,
    /// Sealed; the attacker holds the network key.
    Insider,
    /// `--insecure`.
    Insecure,
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Attack {
    Clean,
    /// The whole of an earlier run's node 0 → 1 traffic, sent to node 1 as soon as it talks to node 0.
    EarlierRun,
    /// Every datagram node 0 sends node 2, sent to node 1 too, from another address.
    Redirect,
    /// A measurement claiming node 0 at each step, 20 m off in x.
    Forge,
    /// Node 0's measurements to node 1 changed on the way (20 m in x where the attacker can; a flipped byte where not).
    Tamper,
    /// 20,000 datagrams of garbage.
    Flood,
    /// A measurement claiming node 0, 190 steps ahead, every 0.5 s.
    StepWalk,
}

/// What one run showed at node 1 (and node 0, for the redirect).
struct Outcome {
    node1: serde_json::Value,
    part1: serde_json::Value,
    /// Node 1's measurements that reached node 0: (in time, late). Late ones reached it too: lateness is the
    /// machine's load, what the redirect attack must not cause is their going elsewhere.
    from1_at_0: (u64, u64),
    wall: Duration,
    recorded: Vec<Vec<u8>>,
}

impl Outcome {
    fn rejected(&self, c: &str) -> u64 {
        self.node1["rejected"][c].as_u64().unwrap_or(0)
    }
    fn counter(&self, c: &str) -> u64 {
        self.node1[c].as_u64().unwrap_or(0)
    }
    fn steps(&self) -> u64 {
        self.part1["steps_done"].as_u64().unwrap_or(0)
    }
    fn error(&self) -> f64 {
        self.node1["networked"]["rms_error"].as_f64().unwrap_or(f64::NAN)
    }
}

fn socket() -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.set_nonblocking(true).unwrap();
    s
}

/// The insider's view: node 0's epoch and node 1's boot as learnt from their traffic, and, once both are known, a
/// sealer that takes over node 0's identity at node 1 (a later epoch, vouched for by a hello echoing node 1's boot).
struct Insider {
    key: Key,
    epoch0: Option<u64>,
    boot1: Option<u64>,
    takeover: Option<Sealer>,
}

impl Insider {
    fn learn(&mut self, from0: Option<&[u8]>, from1: Option<&[u8]>) {
        if let Some(Ok((h, e, _))) = from0.map(claimed) {
            if h.src == 0 {
                self.epoch0.get_or_insert(e);
            }
        }
        if let Some(b) = from1 {
            // Hellos are bound to no boot: any node's key opens a hello sealed for it.
            if let Ok((d, ..)) = Opener::new(&self.key, 0, 0).open(b, |_| true) {
                if let Payload::Hello { boot, .. } = d.payload {
                    self.boot1 = Some(boot);
                }
            }
        }
    }

    /// The takeover hello, once, when both are known.
    fn hello(&mut self) -> Option<Vec<u8>> {
        if self.takeover.is_some() {
            return None;
        }
        let (e0, b1) = (self.epoch0?, self.boot1?);
        let mut s = Sealer::new(&self.key, 0, e0 + 1);
        let hello = Datagram {
            header: Header::hello(0, 1, 1 << 30, Time::ZERO),
            payload: Payload::Hello {
                running: None,
                run: u64::MAX,
                boot: e0 + 1,
                echo: b1,
                probe: 0,
                answer: 0,
            },
        };
        let bytes = s.seal(&hello, 1, 0).ok()?.to_vec();
        self.takeover = Some(s);
        Some(bytes)
    }

    /// `d` sealed for node 1 as node 0, under the takeover.
    fn seal(&mut self, d: &Datagram) -> Option<Vec<u8>> {
        let b1 = self.boot1?;
        Some(self.takeover.as_mut()?.seal(d, 1, b1).ok()?.to_vec())
    }

    /// Node 0's genuine datagram for node 1, opened.
    fn open(&self, b: &[u8]) -> Option<Datagram> {
        Opener::new(&self.key, 1, self.boot1?)
            .open(b, |_| true)
            .ok()
            .map(|(d, ..)| d)
    }
}

/// `d` with 20 m added to the first value of its measurement.
fn moved(mut d: Datagram) -> Datagram {
    if let Payload::Measurement { values, .. } = &mut d.payload {
        values[0] += 20.0;
    }
    d
}

fn run(dir: &Path, key: &Path, mode: Mode, attack: Attack, earlier: &[Vec<u8>]) -> Outcome {
    let d = dir.join(format!("{mode:?}-{attack:?}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let (a1, a2, a3) = (socket(), socket(), socket());
    let port = |s: &UdpSocket| s.local_addr().unwrap().port();
    let free = super::common::free_port;
    let ports = [free(), free(), free()];
    let node = |id: usize, peers: [(usize, u16); 2]| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_simnet"));
        c.args(["node", "-v", "-t", "ring3", "--id", &id.to_string()])
            .args(["--duration", &DURATION_S.to_string(), "--handshake-timeout", "1"])
            .args(["--bind", &format!("127.0.0.1:{}", ports[id])]);
        if mode == Mode::Insecure {
            c.arg("--insecure");
        } else {
            c.arg("--key-file").arg(key);
        }
        for (j, p) in peers {
            c.args(["--peer", &format!("{j}=127.0.0.1:{p}")]);
        }
        c.arg("--out").arg(d.join(format!("n{id}")));
        c
    };
    let k = Key::parse(&std::fs::read_to_string(key).unwrap()).unwrap();
    let wrong = Key::from_bytes([0x5a; 16]);
    let mut insider = Insider {
        key: k,
        epoch0: None,
        boot1: None,
        takeover: None,
    };
    let mut children: Vec<_> = [
        node(0, [(1, port(&a1)), (2, port(&a2))]),
        node(1, [(0, port(&a1)), (2, ports[2])]),
        node(2, [(0, port(&a2)), (1, ports[1])]),
    ]
    .into_iter()
    .map(|mut c| super::common::spawn_until(&mut c, "listening"))
    .collect();
    let started = Instant::now();
    let to = |id: usize| ("127.0.0.1", ports[id]);
    let (mut buf, mut recorded, mut sent_earlier, mut flooded) = (vec![0u8; 2048], Vec::new(), false, 0u32);
    // Node 1 has sent to node 0: it knows node 0's address (before, even an unsealed datagram is from no one).
    let mut heard_1 = false;
    let mut last_walk: Option<Instant> = None;
    // An outsider's forgery claims node 0's current epoch (its clear part shows it) under a key of its own.
    let mut outsider: Option<Sealer> = None;
    let mut ended = [None; 3];
    while ended.iter().any(Option::is_none) {
        for (i, (c, _)) in children.iter_mut().enumerate() {
            if ended[i].is_none() {
                if let Some(s) = c.try_wait().unwrap() {
                    ended[i] = Some((s, started.elapsed()));
                }
            }
        }
        let mut idle = true;
        while let Ok((n, from)) = a1.recv_from(&mut buf) {
            idle = false;
            let b = buf[..n].to_vec();
            if from.port() == ports[1] {
                heard_1 = true;
                if mode == Mode::Insider {
                    insider.learn(None, Some(&b));
                }
                a1.send_to(&b, to(0)).unwrap();
                continue;
            }
            if from.port() != ports[0] {
                continue;
            }
            recorded.push(b.clone());
            if mode == Mode::Insider {
                insider.learn(Some(&b), None);
                if matches!(attack, Attack::Forge | Attack::Tamper | Attack::StepWalk) {
                    if let Some(h) = insider.hello() {
                        a1.send_to(&h, to(1)).unwrap();
                    }
                }
            }
            if attack == Attack::EarlierRun && heard_1 && !sent_earlier {
                sent_earlier = true;
                for e in earlier {
                    a1.send_to(e, to(1)).unwrap();
                }
            }
            let header = peek_header(&b).ok();
            let measurement = header.is_some_and(|h| h.kind == KIND_MEASUREMENT);
            let step = header.map_or(0, |h| h.pertains.step(DURATION_S / STEPS as f64));
            if let (None, Ok((_, e, _))) = (&outsider, claimed(&b)) {
                outsider = Some(Sealer::new(&wrong, 0, e));
            }
            let forged = |d: Datagram, insider: &mut Insider, outsider: &mut Option<Sealer>| match mode {
                Mode::Insecure => d.encode().ok().map(|b| b.to_vec()),
                Mode::Insider => insider.seal(&d),
                Mode::Outsider => outsider.as_mut()?.seal(&d, 1, 0).ok().map(|b| b.to_vec()),
            };
            let fake = |step: u64| Datagram {
                header: Header::new(0, 1, 1 << 30, Time::at_step(step, DURATION_S / STEPS as f64)),
                payload: Payload::measurement(0b111, vec![20.0, 0.0, 0.0]),
            };
            let mut forward = true;
            match attack {
                Attack::Forge if measurement => {
                    let d = match mode {
                        Mode::Insecure => Datagram::decode(&b).ok().map(moved),
                        Mode::Insider => insider.open(&b).map(moved),
                        Mode::Outsider => Some(fake(step)),
                    };
                    if let Some(f) = d.and_then(|d| forged(d, &mut insider, &mut outsider)) {
                        a1.send_to(&f, to(1)).unwrap();
                    }
                }
                Attack::Tamper if measurement => {
                    let t = match mode {
                        Mode::Insecure => Datagram::decode(&b)
                            .ok()
                            .and_then(|d| moved(d).encode().ok())
                            .map(|b| b.to_vec()),
                        Mode::Insider => insider.open(&b).map(moved).and_then(|d| insider.seal(&d)),
                        Mode::Outsider => {
                            // A byte of the sealed payload flipped, the checksum made to match.
                            let mut t = b.clone();
                            let at = t.len() - 4 - 8 - 1;
                            t[at] ^= 0x40;
                            let crc = crc32fast::hash(&t[..t.len() - 4]);
                            let l = t.len();
                            t[l - 4..].copy_from_slice(&crc.to_le_bytes());
                            Some(t)
                        }
                    };
                    if let Some(t) = t {
                        a1.send_to(&t, to(1)).unwrap();
                        forward = false;
                    }
                }
                Attack::StepWalk
                    if measurement && last_walk.is_none_or(|t| t.elapsed() >= Duration::from_millis(500)) =>
                {
                    let ahead = (step + 190).min(STEPS - 1);
                    if let Some(f) = forged(fake(ahead), &mut insider, &mut outsider) {
                        a1.send_to(&f, to(1)).unwrap();
                        last_walk = Some(Instant::now());
                    }
                }
                Attack::Flood if flooded < 20_000 && step > 20 => {
                    for i in 0..2_000u32 {
                        let junk: Vec<u8> = (0..64u32)
                            .map(|j| (i.wrapping_mul(31) ^ j.wrapping_mul(7)) as u8)
                            .collect();
                        let _ = a3.send_to(&junk, to(1));
                    }
                    flooded += 2_000;
                }
                _ => {}
            }
            if forward {
                a1.send_to(&b, to(1)).unwrap();
            }
        }
        while let Ok((n, from)) = a2.recv_from(&mut buf) {
            idle = false;
            if from.port() == ports[0] {
                a2.send_to(&buf[..n], to(2)).unwrap();
                if attack == Attack::Redirect {
                    a2.send_to(&buf[..n], to(1)).unwrap();
                }
            } else if from.port() == ports[2] {
                a2.send_to(&buf[..n], to(0)).unwrap();
            }
        }
        // The attacker's own address hears only probes: nothing to do with them.
        while a3.recv_from(&mut buf).is_ok() {}
        if idle {
            std::thread::sleep(Duration::from_micros(500));
        }
    }
    for (i, (mut c, drain)) in children.into_iter().enumerate() {
        assert!(c.wait().unwrap().success(), "node {i} of {mode:?} {attack:?}");
        drain.join().unwrap();
    }
    let part = |id: usize| -> serde_json::Value {
        serde_json::from_slice(&std::fs::read(d.join(format!("n{id}")).join(format!("node-{id}.json"))).unwrap())
            .unwrap()
    };
    let (p0, p1) = (part(0), part(1));
    let from1_at_0 = p0["part"]["rx"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r[0] == 1)
        .map_or((0, 0), |r| {
            let n = |k: &str| r[1][k].as_u64().unwrap_or(0);
            (n("delivered"), n("late"))
        });
    let _ = std::fs::remove_dir_all(&d);
    Outcome {
        node1: p1["nodes"][0].clone(),
        part1: p1["part"].clone(),
        from1_at_0,
        wall: ended[1].unwrap().1,
        recorded,
    }
}

/// One cell: what happened, and the counter that recorded it.
fn cell(attack: Attack, o: &Outcome, clean: &Outcome) -> String {
    let err = format!("error {:.3} m (clean {:.3})", o.error(), clean.error());
    let counters: Vec<String> = ["bad_tag", "replay", "too_old"]
        .iter()
        .map(|c| (c, o.rejected(c)))
        .chain(
            ["malformed", "implausible_step", "unknown_address"]
                .iter()
                .map(|c| (c, o.counter(c))),
        )
        .filter(|(_, v)| *v > 0)
        .map(|(c, v)| format!("`{c}` {v}"))
        .collect();
    let counted = if counters.is_empty() {
        "nothing counted".to_string()
    } else {
        counters.join(", ")
    };
    let what = match attack {
        Attack::EarlierRun => format!(
            "ran {} of {STEPS} steps from step {}; {err}",
            o.steps(),
            o.part1["first_step"]
        ),
        Attack::Redirect => {
            let (in_time, late) = o.from1_at_0;
            format!(
                "link 1→0 delivered {} of {STEPS} ({late} of them late); {err}",
                in_time + late
            )
        }
        Attack::Flood | Attack::StepWalk => {
            format!("its {} steps in {:.1} s; {err}", o.steps(), o.wall.as_secs_f64())
        }
        _ => err,
    };
    format!("{what}; {counted}")
}

#[test]
#[ignore = "long suite: the book's attack table, about two minutes of node processes (.ci/run runs it)"]
fn wire_attack_table() {
    let dir: PathBuf = std::env::temp_dir().join(format!("simnet-wire-attacks-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let key = super::common::network_key(&dir);
    let modes = [Mode::Outsider, Mode::Insider, Mode::Insecure];
    // Each mode's clean run, its node 0 → 1 traffic the "earlier run" of the replay.
    let clean: Vec<Outcome> = modes.iter().map(|m| run(&dir, &key, *m, Attack::Clean, &[])).collect();
    let rows = [
        (
            "replay of an earlier run (its 0→1 datagrams, at the start)",
            Attack::EarlierRun,
        ),
        (
            "cross-link replay (0→2 datagrams sent to 1: a redirect)",
            Attack::Redirect,
        ),
        ("forgery (node 0's measurement, 20 m off)", Attack::Forge),
        ("tamper (node 0's measurements changed on the way)", Attack::Tamper),
        ("flood (20,000 garbage datagrams)", Attack::Flood),
        ("step walk (190 steps ahead, every 0.5 s)", Attack::StepWalk),
    ];
    let mut table = String::from(
        "| attack on node 1 | sealed, attacker without the key | sealed, attacker holds the key | `--insecure` |\n\
         |---|---|---|---|\n",
    );
    let written = Path::new(env!("CARGO_TARGET_TMPDIR")).join("wire-attack-table.md");
    for (name, attack) in rows {
        let out: Vec<Outcome> = modes
            .iter()
            .zip(&clean)
            .map(|(m, c)| run(&dir, &key, *m, attack, &c.recorded))
            .collect();
        let cells: Vec<String> = out.iter().zip(&clean).map(|(o, c)| cell(attack, o, c)).collect();
        let row = format!("| {name} | {} |", cells.join(" | "));
        println!("{row}");
        table.push_str(&row);
        table.push('\n');
        std::fs::write(&written, &table).unwrap();
        // What the key guarantees against an outsider.
        let (o, c) = (&out[0], &clean[0]);
        assert_eq!(o.steps(), STEPS, "{attack:?}: node 1 did not run every step");
        assert!(
            o.wall.as_secs_f64() >= 0.9 * DURATION_S,
            "{attack:?}: node 1 ended after {:?}",
            o.wall
        );
        assert!(
            o.error() < 2.0 * c.error() + 0.01,
            "{attack:?}: error {} against {} clean",
            o.error(),
            c.error()
        );
        match attack {
            // Sealed for node 1's earlier boot: `bad_tag` before node 0's current boot is vouched for, `too_old`
            // (an earlier boot of node 0) after.
            Attack::EarlierRun => assert!(o.rejected("bad_tag") + o.rejected("too_old") > 150, "{}", o.node1),
            Attack::Redirect => {
                assert!(o.rejected("bad_tag") > 100, "{}", o.node1);
                let (in_time, late) = o.from1_at_0;
                assert!(
                    in_time + late >= STEPS - 10,
                    "link 1→0 delivered {in_time} in time, {late} late"
                );
            }
            Attack::Forge | Attack::Tamper | Attack::StepWalk => {
                assert!(o.rejected("bad_tag") >= 3, "{}", o.node1)
            }
            Attack::Flood => assert!(o.counter("malformed") > 1_000, "{}", o.node1),
            Attack::Clean => {}
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
