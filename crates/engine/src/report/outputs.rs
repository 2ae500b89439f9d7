//! Every file a run and a sweep write, every column of their CSV files and every field of `summary.json`, with what
//! each means: the table the book's "Output files" chapter is generated from ([`markdown`], written by `cargo xtask
//! docs`). Tests hold it to what simnet writes: every file, column and field a run writes is here, and everything
//! here is written by one of the tests' runs.

/// One column of a CSV file or one field of a JSON file. In a field's path, `*` stands for any one name (an
/// estimator, a node id, a filter); in a column, `NAME_*` stands for one column per state component (`true_x`,
/// `true_y`, … for the pose model).
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub means: &'static str,
    /// Written by some runs only (a column of one model).
    pub optional: bool,
}

/// One file (`imu-ID.csv`: one per node).
#[derive(Debug, Clone, Copy)]
pub struct OutputFile {
    pub name: &'static str,
    /// Which command writes it, and when.
    pub written: &'static str,
    pub about: &'static str,
    /// The columns of a CSV file, in order; empty for other files.
    pub columns: &'static [Field],
}

const fn f(name: &'static str, means: &'static str) -> Field {
    Field {
        name,
        means,
        optional: false,
    }
}

const fn only(name: &'static str, means: &'static str) -> Field {
    Field {
        name,
        means,
        optional: true,
    }
}

/// The columns of a filter's figures, as `summary.json` gives them for each node's filters and estimators.
const TRACE: &[Field] = &[
    f("step", "The step k (0-based)."),
    f("t", "Its time k·Δt, s."),
    f("node", "The node id; empty for fused rows."),
    f("estimator", "`networked` (the node's β-weighted consensus filter), `independent` (its own sensor only), a distributed estimator the run holds (`kcf`, `icf`, `ci`, …: its posterior at that node), `fused` (covariance intersection over the nodes, ω = 0.5) or `fused_median` (its 20-sample centred median, pose)."),
    f("true_*", "The true state, one column per component (pose: x, y, z, roll, pitch, yaw; attitude: roll, pitch, yaw in rad; linear: x0, x1, …)."),
    f("est_*", "The estimate, in the same components."),
    f("var_*", "The posterior variance of each component (for ±3σ bands)."),
    f("error", "The step's error figure: position error in m (pose), rotation angle in degrees (attitude), state error (linear)."),
    f("trace_p_prior", "Trace of the predicted covariance."),
    f("trace_p_post", "Trace of the posterior covariance."),
    f("received", "The source ids whose measurements the update used, separated by `;` (empty for a distributed estimator's row)."),
    f("feasible", "Whether the LMI guard's conditions (17), (19) held (networked)."),
    f("nees", "The normalised estimation error squared (consistent ≈ the state dimension)."),
    f("diverged", "Whether trace P passed `sim.divergence_trace`."),
];

const LINKS: &[Field] = &[
    f("from", "The sending node's id."),
    f("to", "The receiving node's id."),
    f("sent", "Datagrams the sender sent once."),
    f("delivered", "Accepted in time, duplicates excluded."),
    f("late", "Arrived after its step's deadline: not used."),
    f("corrupted", "Failed the checksum."),
    f("lost", "Dropped by the loss model, a scheduled fault or the socket layer: sent = delivered + late + corrupted + lost."),
    f("lost_random", "Of those, dropped by the loss model."),
    f("lost_down", "Of those, dropped by a scheduled fault (a link down, a partition, a crashed end)."),
    f("duplicated", "Extra copies the link made (not part of sent)."),
    f("loss_rate", "lost / sent."),
    f("arrival_rate", "The fraction of the receiver's steps in which a measurement from the sender arrived in time: the arrival rate λ (γ in the printed table)."),
    f("mean_loss_run", "The mean run of consecutive losses, datagrams."),
    f("longest_loss_run", "The longest run of consecutive losses, datagrams."),
    only("frames", "Radio runs: the frames the sender put on the air for the receiver (retries included)."),
    only("distance_m", "Radio runs: their mean distance as each began, m."),
    only("rssi_dbm", "Radio runs: the mean power at the receiver of the frames it heard (above a hundredth of its noise), dBm."),
    only("sinr_db", "Radio runs: the mean of the lowest SINR over each frame it locked onto, dB."),
    only("lqi", "Radio runs: the mean link quality indication (0–255) of the frames it locked onto: each frame's chance to arrive intact scaled to 0–255, as ns-3 gives it."),
    only("prr", "Radio runs: frames that arrived intact over frames sent (by frame; `loss_rate` counts messages)."),
];

const MEASUREMENTS: &[Field] = &[
    f("step", "The step."),
    f("t", "Its time, s."),
    f("node", "The sensing node's id."),
    f("channel", "The measurement channel (0 unless `sim.split_channels`: pose 0 position, 1 orientation; attitude 0 accelerometer, 1 magnetometer)."),
    f("rows", "The rows of the model's observation the channel carries, separated by `;`."),
    f("values", "Their values, separated by `;`."),
    f("r", "R over those rows, row-major, separated by `;`."),
];

const CAPTURE: &[Field] = &[
    f("t", "When the datagram was sent, or when the copy was due at its receiver, s (whole nanoseconds)."),
    f("event", "`sent` (handed to the medium) or `delivered` (a copy the medium delivered)."),
    f("from", "The sending node's id."),
    f("to", "The receiving node's id; empty for a broadcast as sent (each copy delivered names its receiver)."),
    f("datagram", "The sender's number for the datagram (0, 1, … in sending order); on a `delivered` line the datagram it is a copy of, empty when its bytes match nothing the sender sent (a bit flipped on the way). A number sent with no `delivered` line to a receiver was lost to it; two lines, duplicated."),
    f("bytes", "Its length, bytes."),
    f("stream", "The link's stream that decided its fate: `measurement` (the measurements, with the round-0 messages beside them) or `round-R`; empty for a corrupted copy."),
];

const ESTIMATORS: &[Field] = &[
    f("step", "The step."),
    f("t", "Its time, s."),
    f("estimator", "The estimator's name (`simnet estimators`)."),
    f("node", "The node id (the fusion center's for the centralized schemes)."),
    f("error", "The step's error figure, as in trace.csv."),
    f("values", "The estimate, separated by `;`."),
];

const IMU: &[Field] = &[
    f("t", "Time, s."),
    f("ax", "Accelerometer x, m/s² (specific force in the body frame)."),
    f("ay", "Accelerometer y, m/s²."),
    f("az", "Accelerometer z, m/s²."),
    f("gx", "Gyroscope x, rad/s."),
    f("gy", "Gyroscope y, rad/s."),
    f("gz", "Gyroscope z, rad/s."),
    only("mx", "Magnetometer x (attitude model only), unit of `model.mag_field`."),
    only("my", "Magnetometer y (attitude model only)."),
    only("mz", "Magnetometer z (attitude model only)."),
    f("x", "True position x, m."),
    f("y", "True position y, m."),
    f("z", "True position z, m."),
    f("roll", "True roll, rad."),
    f("pitch", "True pitch, rad."),
    f("yaw", "True yaw, rad."),
];

const POINTS: &[Field] = &[
    f("point", "The point's index in the plan."),
    f("KEY", "One column per swept key: its value at the point."),
    f(
        "estimator",
        "The estimator, or `network` for the network's own figures (loss).",
    ),
    f(
        "metric",
        "The figure (`mean_error`, `ratio_to_centralized`, `loss_rate`, …).",
    ),
    f("n", "The runs (seeds) it is taken over."),
    f("mean", "Their mean."),
    f("sd", "Their standard deviation."),
    f("ci95_low", "The 95 % confidence interval's lower end (Student's t)."),
    f("ci95_high", "Its upper end."),
];

const RUNS: &[Field] = &[
    f("point", "The point's index in the plan."),
    f("KEY", "One column per swept key: its value at the point."),
    f("seed", "The run's seed."),
    f("run", "The run's digest (scenario and seed): its file in `runs/`."),
    f("steps", "Steps run."),
    f("loss_rate", "The measured fraction of datagrams lost over every link."),
    f("arrival_rate", "The mean arrival rate over every link."),
    f("fused_error", "The fused (covariance intersection) estimate's mean error."),
    f("socket_losses", "Frames of the virtual clock lost in the socket layer."),
    only("channel_load", "A campaign over a radio channel: the channel's load (`radio.channel_load` of summary.json); this column and the next three are written only where a run was over a radio."),
    only("airtime_s", "Every node's time on the air, summed, s."),
    only("energy_j", "Every node's radio energy, J."),
    only("mean_power_mw", "A node's mean radio power, mW (the mean over the nodes)."),
    f("ESTIMATOR.*", "Per estimator: mean_error, median_error, ratio_to_centralized, rms_error, disagreement, fused_error, trace_p, nees, diverged, messages, bytes (as in summary.json)."),
];

/// Every file a run (`simnet run`, `simnet collect`), a node (`simnet node --out`) and a sweep write.
pub const FILES: &[OutputFile] = &[
    OutputFile { name: "summary.json", written: "run, collect", about: "The run's figures and how it was made (its fields below).", columns: &[] },
    OutputFile { name: "trace.csv", written: "run, collect", about: "One row per step, node and estimator (the two filters, then each distributed estimator the run holds), and per step the fused estimate; written row by row during the run (memory does not grow with its length). Fused rows have no node and fill the columns the fusion covers; `fused_median` rows come 10 steps after their step's node rows. Numbers are in their shortest round-trip form; empty = unknown.", columns: TRACE },
    OutputFile { name: "links.csv", written: "run, collect", about: "One row per directed link (the run's link table).", columns: LINKS },
    OutputFile { name: "measurements.csv", written: "run", about: "Every measurement each sensing node took, one line per node, step and channel, as it was taken (before any link decided its fate): enough to recompute any node's filter outside simnet.", columns: MEASUREMENTS },
    OutputFile { name: "capture.csv", written: "run --capture", about: "Every datagram the nodes sent and every copy the medium delivered, in order of time: a packet capture at both ends of every link (a tap on the medium that changes nothing it carries). Memory grows with the run: 80 bytes a line (one per datagram sent, one per copy delivered) and some 50 a datagram sent, while the run goes.", columns: CAPTURE },
    OutputFile { name: "estimators.csv", written: "run, with distributed estimators", about: "Every distributed estimator's estimate per step and node.", columns: ESTIMATORS },
    OutputFile { name: "imu-ID.csv", written: "run, per simulated sensing node of a pose or attitude model", about: "The node's IMU samples and true pose, in the format simnet reads back (see Recordings); also streamed.", columns: IMU },
    OutputFile { name: "trajectory.svg", written: "run, collect", about: "Truth and estimates in the x–y plane at equal scale (pose); roll, pitch and yaw in three panels (attitude); the states (linear).", columns: &[] },
    OutputFile { name: "error.svg", written: "run, collect", about: "The error over time, networked against independent, the fused estimate in black; the burn-in and every fault window shaded. Up to 6 nodes each filter is a line; beyond, the median and min–max band across nodes.", columns: &[] },
    OutputFile { name: "map.svg", written: "run", about: "Where the nodes stand at the start (x–y, equal scale) and each linked pair coloured by the fraction of its datagrams delivered, both directions pooled; written when the nodes stand apart (a linear system's positions, rgg50's graph), not for an IMU network's nodes on one package.", columns: &[] },
    OutputFile { name: "trace_p.svg", written: "run, collect", about: "Trace P over time on a log scale, shaded as error.svg.", columns: &[] },
    OutputFile { name: "estimators.svg", written: "run, with distributed estimators", about: "Every estimator's median-over-nodes error, the centralized reference in black.", columns: &[] },
    OutputFile { name: "report.html", written: "run, collect, sweep", about: "One self-contained page: the command and conditions, the tables, every plot inline, the provenance and the resolved scenario.", columns: &[] },
    OutputFile { name: "NAME.parquet", written: "run, sweep, with `--format parquet` (the parquet feature)", about: "A Parquet copy of each CSV file, with the same columns.", columns: &[] },
    OutputFile { name: "node-ID.json", written: "node --out", about: "The node's part: its summary with the raw link counters `simnet collect` joins into per-link figures (its `part` field).", columns: &[] },
    OutputFile { name: "trace-ID.csv", written: "node --out", about: "The node's rows of trace.csv.", columns: TRACE },
    OutputFile { name: "estimates-ID.csv", written: "node --out", about: "The node's estimates per step (the networked filter's — `nan` throughout where the node has none — and each estimator's x and P), from which collect builds the fused estimates.", columns: &[] },
    OutputFile { name: ".simnet-outputs", written: "run, collect", about: "The files the last whole run wrote into the directory: a later run removes only those of them it does not write again, never a file simnet did not write.", columns: &[] },
    OutputFile { name: ".simnet-lock", written: "run, collect", about: "Held while a run writes the directory: two runs into one directory do not mix their files.", columns: &[] },
    OutputFile { name: "plan.json", written: "sweep", about: "The campaign: the base scenario, the swept keys and their values, the seeds, every point.", columns: &[] },
    OutputFile { name: "manifest.json", written: "sweep", about: "Who ran it: simnet's version and commit, the command, the base scenario's digest, per shard its start, end, cores and runs.", columns: &[] },
    OutputFile { name: "runs/DIGEST.json", written: "sweep", about: "One run's figures, as its row of runs.csv (its key, point, swept values, seed, steps, the network's and each estimator's figures): a sweep resumes by skipping the runs it finds.", columns: &[] },
    OutputFile { name: "shards/SHARD.DIGEST.json", written: "sweep", about: "What each shard (`all`, or I-of-N) ran: its command, start and end, cores and runs; `sweep merge` joins them.", columns: &[] },
    OutputFile { name: "runs.csv", written: "sweep", about: "One row per run.", columns: RUNS },
    OutputFile { name: "points.csv", written: "sweep", about: "One row per point, estimator and figure, over the seeds.", columns: POINTS },
    OutputFile { name: "sweep.svg", written: "sweep", about: "Each figure against the first swept key, a line per estimator with its 95 % band.", columns: &[] },
];

/// Every field of `summary.json`.
pub const SUMMARY: &[Field] = &[
    f("simnet_version", "The simnet version that wrote the file."),
    f("topology", "The topology's name."),
    f("source", "Where it was read from (`builtin:ring3`, a path)."),
    f("model", "pose | attitude | linear, or the name of a model the program registered."),
    f("seed", "The run's seed."),
    f("clock", "virtual (lockstep), realtime (wall clock) or multi-host (merged parts)."),
    f("rate_hz", "The step rate."),
    f("steps", "Steps run."),
    f("burn_in_steps", "Steps left out of every mean."),
    f("interrupted", "Whether the run was stopped (Ctrl-C) before its end: the figures are over the steps run."),
    f("transport.wall_s", "Wall time of the run, s: what the machine decided (every field of `transport` is left out of any comparison of two runs)."),
    f("transport.frames_resent", "Frames of the virtual clock sent again because the kernel had dropped them."),
    f("transport.kernel_drops.*", "Datagrams the kernel dropped on a node's socket, by node id."),
    f("transport.schedule.max_lag_ms", "A wall-clock run: the largest lag of a step's start behind its schedule."),
    f("transport.schedule.late_steps", "Node-steps that started more than one period late."),
    f("transport.schedule.steps", "Node-steps measured."),
    f("socket_losses", "Frames of the virtual clock lost for good in the socket layer."),
    f("nodes[].id", "The node id."),
    f("nodes[].role", "peer | sensor | estimator."),
    f("nodes[].*.mean_error", "For its `networked` and `independent` filters: the mean error after the burn-in (m for pose, degrees for attitude, state units for linear); null for a node fed from a file without reference columns. `networked` is null as a whole for a node that runs no networked filter (a model whose nodes observe differently, such as ranges from where each stands)."),
    f("nodes[].*.rms_error", "The RMS error after the burn-in."),
    f("nodes[].*.final_error", "The error at the last step."),
    f("nodes[].*.mean_trace_p_prior", "The mean trace of the predicted covariance."),
    f("nodes[].*.mean_trace_p_post", "The mean trace of the posterior covariance."),
    f("nodes[].*.max_trace_p_post", "Its largest value."),
    f("nodes[].*.nees_mean", "The mean NEES (consistent ≈ the state dimension)."),
    f("nodes[].*.diverged", "Whether trace P passed `sim.divergence_trace`."),
    f("nodes[].*.lmi_feasible_fraction", "networked: the fraction of steps after the burn-in on which the LMI guard held."),
    f("nodes[].*.lmi_infeasible_steps", "networked: the steps on which it did not (every step)."),
    f("nodes[].error_ratio", "networked / independent mean error."),
    f("nodes[].malformed", "Datagrams refused as malformed."),
    f("nodes[].corrupted", "Datagrams that failed the checksum."),
    f("nodes[].restarts", "Restarts after a crash."),
    f("nodes[].steps_down", "Steps the node was down."),
    f("nodes[].rejected.*", "Datagrams refused by authentication, by cause: bad_tag, replay, too_old, unknown_source."),
    f("nodes[].implausible_step", "Datagrams whose step was implausibly far from the node's."),
    f("nodes[].unknown_address", "Datagrams from an address no neighbour has."),
    f("nodes[].gated", "Neighbours' measurements the innovation gate left out."),
    f("links[].*", "Each directed link's figures, as the columns of links.csv, and `delivered_fraction` (delivered / sent), `gated` (the sender's measurements the receiver's gate left out) and `seq_gaps` (datagrams the sender numbered for the receiver that never came intact, counted by the receiver from the gaps in their sequence numbers)."),
    f("fused.nodes", "The nodes fused."),
    f("fused.omega", "The covariance intersection weight."),
    f("fused.mean_error", "The fused estimate's mean error."),
    f("fused.mean_trace_p", "Its mean trace P."),
    f("fused.median_mean_error", "The 20-sample median-filtered estimate's mean error (pose)."),
    f("fused.optimal_mean_error", "The trace-optimal fusion's mean error (ω chosen at each stage)."),
    f("fused.optimal_mean_trace_p", "Its mean trace P."),
    f("estimators.*.mean_error", "Per distributed estimator: the mean over nodes of each node's mean error."),
    f("estimators.*.median_error", "The median over nodes."),
    f("estimators.*.ratio_to_centralized", "Its mean error / the centralized reference's."),
    f("estimators.*.disagreement", "The mean spread of the nodes' estimates."),
    f("estimators.*.fused_error", "The mean error, after the burn-in, of the nodes' estimates fused by covariance intersection (ω = 0.5), as `fused` for the two filters; null for the fusion centers."),
    f("estimators.*.diverged", "Nodes whose estimate diverged."),
    f("estimators.*.messages", "Messages it sent."),
    f("estimators.*.bytes", "Bytes it sent."),
    f("estimators.*.delivered", "Messages delivered (centralized-net: to the fusion center)."),
    f("estimators.*.nodes[].id", "Per node: its id, and the figures of `nodes[].networked` for this estimator."),
    f("estimators.*.nodes[].*", "The node's figures for this estimator (mean_error, rms_error, final_error, trace P, NEES, diverged, …)."),
    f("settings.duration_s", "Simulated duration, s."),
    f("settings.burn_in_s", "The burn-in, s."),
    f("settings.deadline_s", "A measurement's deadline after its step, s."),
    f("settings.trajectory", "The body's motion."),
    f("settings.split_channels", "Whether measurement channels travel in datagrams of their own."),
    f("settings.rounds", "Consensus rounds per step."),
    f("settings.overrides.*", "Each command-line or environment override applied to the file (loss, delay_ms, duration_s, auth, …)."),
    f("settings.links[].*", "Each directed link's resolved settings: from, to, loss (model, p, …), delay_ms, jitter_ms, jitter, duplicate, corrupt."),
    f("settings.scenario", "The resolved scenario as TOML: `simnet -t FILE` on it reproduces the run."),
    f("settings.scenario_sha256", "Its SHA-256."),
    f("settings.faults[].kind", "crash | link-down | partition."),
    f("settings.faults[].nodes", "The crashed node, the link's two ends, or the partitioned nodes."),
    f("settings.faults[].directed", "link-down: from the first node to the second only."),
    f("settings.faults[].start_s", "When the fault starts, s."),
    f("settings.faults[].end_s", "When it ends (absent: to the end of the run)."),
    f("part.*", "In a node's part (node-ID.json) only: its id, first step, steps done, raw link counters and fusion layout."),
    f("security.aead", "The authentication: AES-128-CCM with 8-byte tags."),
    f("security.key", "The key file, or `seed` (an in-process run's own key)."),
    f("security.rejected.*", "Datagrams refused at every node, by cause."),
    f("attacks[].kind", "forge | tamper | replay | flood | false-data."),
    f("attacks[].target", "The node attacked."),
    f("attacks[].claim", "The source claimed."),
    f("attacks[].node", "false-data: the compromised node."),
    f("attacks[].start_s", "When the attack started, s."),
    f("attacks[].end_s", "When it ended."),
    f("attacks[].datagrams.sent", "The attacker's datagrams sent."),
    f("attacks[].datagrams.used", "Of those, used by a filter."),
    f("attacks[].datagrams.ignored", "Accepted but not used (late, superseded)."),
    f("attacks[].datagrams.rejected.*", "Refused, by cause (bad_tag, replay, too_old, unknown_source, malformed, corrupted, implausible_step, unknown_address)."),
    f("attacks[].gated", "Measurements of the attacked source the target's gate left out."),
    f("attacks[].gated_clean", "The same in the clean run of the same seed."),
    f("radio.span_s", "Radio runs: how long the radios were on — the run, and past its last step while saturated queues drained, s."),
    f("radio.tx_dbm", "The radios' transmit power, dBm."),
    f("radio.sensitivity_dbm", "Their sensitivity, dBm."),
    f("radio.channel_load", "The senders' airtime summed over the span."),
    f("radio.energy_j", "Every node's radio energy, J."),
    f("radio.energy_model", "The chip, currents and supply the energy is costed at."),
    f("radio.nodes[].*", "Per node: id, frames, airtime_s, duty (airtime over the span), busy_assessments, csma_failures, acks (ACK frames sent), retries, no_ack (unicasts given up), energy_j, mean_power_mw."),
    f("attack_effect[].id", "Per estimating node: its id."),
    f("attack_effect[].mean_error", "Its networked mean error under attack."),
    f("attack_effect[].clean_mean_error", "The same in the clean run."),
    f("attack_effect[].rms_error", "Its RMS error under attack."),
    f("attack_effect[].clean_rms_error", "The same in the clean run."),
];

/// Whether a field pattern (`nodes[].*.mean_error`) names `path` (`nodes[].networked.mean_error`): one name per
/// `*`, a trailing `*` for any rest.
pub fn matches(pattern: &str, path: &str) -> bool {
    let (p, q): (Vec<&str>, Vec<&str>) = (pattern.split('.').collect(), path.split('.').collect());
    if p.last() == Some(&"*") && q.len() >= p.len() {
        return p[..p.len() - 1].iter().zip(&q).all(|(a, b)| *a == "*" || a == b);
    }
    p.len() == q.len() && p.iter().zip(&q).all(|(a, b)| *a == "*" || a == b)
}

/// The book's generated pages, each with its path from the repository's root and its text (`cargo xtask docs` writes
/// them; a test holds the committed ones to it).
pub fn book_pages() -> [(&'static str, String); 2] {
    [
        ("docs/src/generated/keys.md", crate::scenario::schema::markdown()),
        ("docs/src/generated/outputs.md", markdown()),
    ]
}

/// The chapter: each file with who writes it and its columns, then every field of summary.json.
pub fn markdown() -> String {
    use std::fmt::Write;
    let cell = crate::text::markdown_cell;
    let mut out = String::from(
        "<!-- generated by `cargo xtask docs` from simnet::report::outputs: do not edit by hand -->\n\n\
         | file | written by | what |\n|---|---|---|\n",
    );
    for file in FILES {
        let _ = writeln!(
            out,
            "| `{}` | {} | {} |",
            file.name,
            cell(file.written),
            cell(file.about)
        );
    }
    for file in FILES.iter().filter(|f| !f.columns.is_empty()) {
        let _ = write!(out, "\n#### `{}`\n\n| column | meaning |\n|---|---|\n", file.name);
        for c in file.columns {
            let _ = writeln!(out, "| `{}` | {} |", c.name, cell(c.means));
        }
    }
    out.push_str("\n#### `summary.json`\n\n| field | meaning |\n|---|---|\n");
    for field in SUMMARY {
        let _ = writeln!(out, "| `{}` | {} |", field.name, cell(field.means));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pattern_names_one_level_per_star() {
        assert!(matches("nodes[].*.mean_error", "nodes[].networked.mean_error"));
        assert!(!matches("nodes[].*.mean_error", "nodes[].mean_error"));
        assert!(matches("links[].*", "links[].sent"));
        assert!(matches("part.*", "part.links_out.1.sent"));
        assert!(!matches("fused.nodes", "fused.omega"));
    }
}
