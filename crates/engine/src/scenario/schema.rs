//! Every key a topology file has, with its type, unit, default, range and meaning: the table the book's "Topology
//! file keys" chapter is generated from ([`markdown`], written by `cargo xtask docs`). Tests hold it to the
//! validator: every key the file format accepts is here and every key here is accepted; a value outside a key's
//! range is refused with a problem naming that key; and leaving a key out runs exactly as giving its default.

/// One key of a topology file.
#[derive(Debug, Clone, Copy)]
pub struct KeyDoc {
    /// Its path in the file: `sim.rate_hz`; `node[].sensor` for every entry of a list.
    pub key: &'static str,
    /// number, integer, bool, string, one of a list of words, `[x, y, z]`, a matrix …
    pub kind: &'static str,
    pub unit: &'static str,
    /// The value when the key is left out: a TOML value where one value is the default (tests give it and compare
    /// the run with the run without it), else words.
    pub default: &'static str,
    /// The values accepted.
    pub range: &'static str,
    pub means: &'static str,
    /// A value outside the range, which validation must refuse naming this key (tests try it).
    pub refused: Option<&'static str>,
}

const fn k(
    key: &'static str,
    kind: &'static str,
    unit: &'static str,
    default: &'static str,
    range: &'static str,
    means: &'static str,
    refused: Option<&'static str>,
) -> KeyDoc {
    KeyDoc {
        key,
        kind,
        unit,
        default,
        range,
        means,
        refused,
    }
}

const NUM: &str = "number";
const INT: &str = "integer";
const BOOL: &str = "bool";
const STR: &str = "string";
const VEC3: &str = "[x, y, z]";
const MATRIX: &str = "matrix (list of rows)";
const PROB: &str = "[0, 1]";
const POS: &str = "> 0, finite";
const NONNEG: &str = "≥ 0, finite";

/// Every key of a topology file, table by table, in the order of the chapter.
pub const KEYS: &[KeyDoc] = &[
    // The file.
    k("name", STR, "", "the file's name without `.toml`", "any", "The topology's name in outputs and titles.", None),
    k("description", STR, "", "\"\"", "any", "One line said by `simnet topologies` and `validate`.", None),
    // [sim]
    k("sim.rate_hz", NUM, "Hz", "100.0", "> 0, at most 1e6", "Step rate: every node predicts, senses and sends once per step.", Some("0")),
    k("sim.duration_s", NUM, "s", "30.0", "> 0, at least one step, at most 1e8 steps", "Simulated time.", Some("-1")),
    k("sim.burn_in_s", NUM, "s", "3 s or a tenth of the duration, the shorter", "≥ 0, shorter than the duration", "The start left out of every mean (the filters' transient).", Some("1e9")),
    k("sim.seed", INT, "", "1", "0 to 2⁶⁴ − 1", "The run's random seed: every random stream (noise, loss, truth) derives from it.", Some("-1")),
    k("sim.trajectory", "spiral | circle | line | rest | piecewise | figure8 | tumble", "", "\"spiral\"", "the words listed; IMU-driven models only (pose, attitude)", "The body's true motion (tumble: turning in place).", Some("\"zigzag\"")),
    k("sim.deadline_ms", NUM, "ms", "one period (1000 / rate_hz)", "> 0, at most one period", "A measurement of step k counts only if it arrives by t_k + deadline.", Some("0")),
    k("sim.split_channels", BOOL, "", "false", "true | false", "One datagram per measurement channel (pose: position, orientation; attitude: accelerometer, magnetometer), so that a link can lose part of a measurement.", None),
    k("sim.divergence_trace", NUM, "", "1e6", POS, "A filter whose trace P exceeds this is marked diverged.", Some("0")),
    // [model]
    k("model.kind", "pose | attitude | linear | a registered name", "", "\"pose\"", "the words listed, or a model the program registered", "pose: state [p, v, θ] driven by the node's IMU, z = [p, θ]; attitude: a quaternion EKF, z = [accelerometer, magnetometer]; linear: x⁺ = A x + w, y = C x + v; any other: a model a program registered with `simnet::model::register`.", Some("\"nope\"")),
    k("model.q_pos", NUM, "m² per step", "0.0", NONNEG, "pose: process noise added to the position variance each step, beyond what the IMU's noise densities imply.", Some("-1")),
    k("model.q_vel", NUM, "(m/s)² per step", "0.0", NONNEG, "pose: the same for velocity.", Some("-1")),
    k("model.q_att", NUM, "rad² per step", "0.0", NONNEG, "pose: the same for attitude.", Some("-1")),
    k("model.r_pos", NUM, "m²", "0.01", POS, "pose: the filter's position measurement noise variance R (Sequeira (2023) §2.2).", Some("0")),
    k("model.r_att", NUM, "rad²", "0.001", POS, "pose: the filter's attitude measurement noise variance.", Some("0")),
    k("model.p0_pos", NUM, "m²", "0.25", POS, "pose: initial position variance P₀.", Some("0")),
    k("model.p0_vel", NUM, "(m/s)²", "0.01", POS, "pose: initial velocity variance.", Some("0")),
    k("model.p0_att", NUM, "rad²", "0.003", POS, "pose and attitude: initial attitude variance.", Some("0")),
    k("model.r_acc", NUM, "(m/s²)²", "0.01", POS, "attitude: the filter's accelerometer noise variance.", Some("0")),
    k("model.r_mag", NUM, "(unit of mag_field)²", "1e-5", POS, "attitude: the filter's magnetometer noise variance.", Some("0")),
    k("model.mag_field", VEC3, "any unit (a direction)", "[0.25, 0.0, -0.433]", "finite, not zero", "attitude: the magnetic field in the navigation frame.", Some("[0.0, 0.0, 0.0]")),
    k("model.a", MATRIX, "", "required (linear)", "n × n, finite", "linear: the state transition A.", Some("[[1.0, 2.0]]")),
    k("model.c", MATRIX, "", "required (linear)", "m × n (m ≤ 64), finite", "linear: the observation matrix C.", Some("[[1.0, 2.0]]")),
    k("model.q", MATRIX, "", "required (linear)", "n × n, symmetric positive semidefinite", "linear: the process noise covariance Q: the truth is driven by w ~ N(0, Q).", Some("[[-1.0]]")),
    k("model.r", MATRIX, "", "required (linear)", "m × m, symmetric positive definite", "linear: the measurement noise covariance R: y = C x + v, v ~ N(0, R).", Some("[[0.0]]")),
    k("model.x0", "list of numbers", "", "zeros", "n entries", "linear: the initial estimate x̂₀, and the mean the true initial state is drawn from (x(0) ~ N(x0, p0); then the truth runs x⁺ = A x + w on its own seeded stream).", Some("[1.0, 2.0, 3.0]")),
    k("model.p0", MATRIX, "", "the identity", "n × n, symmetric positive definite", "linear: the initial covariance P₀, and the spread the true initial state is drawn with.", Some("[[0.0]]")),
    k("model.observe", "state | ranges", "", "\"state\"", "the words listed; linear only", "linear: what each node measures. state: y = C x + v; ranges: its distance to the body whose position is the first two state rows, from where the node stands (node[].position_m), with variance model.r (1 × 1) and no model.c; every estimator linearises each range at its node's site, and the nodes run no networked filter (sequeira's one gain needs one observation for every source).", Some("\"bearing\"")),
    k("model.params", "table", "", "empty", "the keys the registered model reads", "a registered model's own keys (`[model.params]`), which it checks and reports by key (`model.params.<key>`).", Some("{ q = 1.0 }")),
    // [consensus]
    k("consensus.beta0", NUM, "", "0.0", PROB, "β₀ of Sequeira (2023) (17): the weight of the node's own prior in the consensus step.", Some("2")),
    k("consensus.self", NUM, "", "1.0", NONNEG, "β_i^i: the weight of the node's own measurement.", Some("-1")),
    k("consensus.neighbor", NUM, "", "0.0", NONNEG, "β_j^i for every neighbour j.", Some("-1")),
    k("consensus.matrix", MATRIX, "", "from self and neighbor", "N × N, entries ≥ 0; row i = receiving node i", "Every β_j^i at once, instead of self and neighbor.", Some("[[1.0]]")),
    k("consensus.weights", "metropolis", "", "none (self and neighbor)", "\"metropolis\"", "β from the graph: πᵢⱼ = 1/(1 + max(dᵢ, dⱼ)), each row over the measurements the node can have, renormalised to sum to one.", Some("\"uniform\"")),
    k("consensus.lmi", "table", "", "", "alpha, gamma, enabled", "The LMI guard of Sequeira (2023) (17), (19).", None),
    k("consensus.lmi.alpha", NUM, "", "1000.0", POS, "α of the LMI guard.", Some("0")),
    k("consensus.lmi.gamma", NUM, "", "1e-5", NONNEG, "γ of the LMI guard.", Some("-1")),
    k("consensus.lmi.enabled", BOOL, "", "true", "true | false", "Whether the guard runs (off: the β step is taken whatever the LMI says).", None),
    k("consensus.inflation", NUM, "", "1000.0", "≥ 1, finite", "λ: the variance inflation of a channel no source delivered in a step.", Some("0.5")),
    k("consensus.gate", NUM, "", "none (no gate)", "(0, 1)", "The innovation gate: a neighbour's measurement whose normalised innovation squared exceeds this χ² quantile is left out.", Some("1")),
    // [sensor]
    k("sensor", "table", "", "an MPU-6050", "the keys below", "Every node's sensor; `[node.sensor]` overrides per node (`node[].sensor`, the same keys).", None),
    k("sensor.accel_noise", NUM, "m/s²/√Hz", "0.003924", NONNEG, "Accelerometer noise density (400 µg/√Hz, g = 9.81 m/s²).", Some("-1")),
    k("sensor.gyro_noise", NUM, "rad/s/√Hz", "8.726646259971648e-5", NONNEG, "Gyroscope noise density (0.005 °/s/√Hz).", Some("-1")),
    k("sensor.accel_bias", VEC3, "m/s²", "[0.0, 0.0, 0.0]", "finite", "A constant accelerometer bias.", Some("[nan, 0.0, 0.0]")),
    k("sensor.gyro_bias", VEC3, "rad/s", "[0.0, 0.0, 0.0]", "finite", "A constant gyroscope bias.", Some("[nan, 0.0, 0.0]")),
    k("sensor.accel_drift", VEC3, "m/s² per step", "[0.0, 0.0, 0.0]", "finite, ≥ 0", "The standard deviation of the accelerometer bias's random walk per step (Sequeira (2023): a_offset_k = a_offset_k−1 + 0.05·randn).", Some("[-1.0, 0.0, 0.0]")),
    k("sensor.gyro_drift", VEC3, "rad/s per step", "[0.0, 0.0, 0.0]", "finite, ≥ 0", "The same for the gyroscope bias.", Some("[-1.0, 0.0, 0.0]")),
    k("sensor.pos_noise", NUM, "m²", "0.01", NONNEG, "pose: the variance of the position fixes the sensor takes.", Some("-1")),
    k("sensor.att_noise", NUM, "rad²", "0.001", NONNEG, "pose: the variance of the attitude fixes.", Some("-1")),
    k("sensor.mag_noise", NUM, "(unit of mag_field)²", "4e-6", NONNEG, "attitude: the magnetometer noise variance (2 mG on a 0.5 G field).", Some("-1")),
    // [link]
    k("link", "table", "", "a perfect link", "the keys below", "Every link's defaults; an `[[edge]]` may override any of them (`edge[].loss`, `edge[].delay_ms`, …).", None),
    k("link.loss", "table", "", "{ model = \"bernoulli\", p = 0.0 }", "the keys below", "The loss process of a link.", None),
    k("link.loss.model", "bernoulli | gilbert-elliott", "", "bernoulli, or gilbert-elliott when a key only it has is given", "the words listed", "Independent losses, or the two-state burst channel (netem's `loss gemodel p r 1-h 1-k`).", Some("\"markov\"")),
    k("link.loss.p", NUM, "", "0.0", PROB, "Bernoulli: the loss probability. Gilbert–Elliott: the probability of going good → bad.", Some("1.5")),
    k("link.loss.r", NUM, "", "required (gilbert-elliott, with p)", PROB, "Gilbert–Elliott: the probability of going bad → good.", Some("1.5")),
    k("link.loss.one_minus_h", NUM, "", "1.0", PROB, "Gilbert–Elliott: the loss probability in the bad state.", Some("1.5")),
    k("link.loss.one_minus_k", NUM, "", "0.0", PROB, "Gilbert–Elliott: the loss probability in the good state.", Some("1.5")),
    k("link.loss.rate", NUM, "", "none", PROB, "Gilbert–Elliott given as its stationary loss rate (with burst); Bernoulli: the same as p.", Some("1.5")),
    k("link.loss.burst", NUM, "datagrams", "none", "≥ 1", "Gilbert–Elliott: the mean loss run (r = 1/burst).", Some("0.5")),
    k("link.delay_ms", NUM, "ms", "0.0", "≥ 0, at most 1e7", "A constant one-way delay.", Some("-1")),
    k("link.jitter_ms", NUM, "ms", "0.0", "≥ 0, at most 1e7", "Jitter added to the delay (see jitter).", Some("-1")),
    k("link.jitter", "uniform | normal", "", "\"uniform\"", "the words listed", "uniform: ± jitter_ms; normal: σ = jitter_ms.", Some("\"pareto\"")),
    k("link.duplicate", NUM, "", "0.0", PROB, "The probability that a datagram is delivered twice.", Some("1.5")),
    k("link.corrupt", NUM, "", "0.0", PROB, "The probability that one bit of a datagram flips (the receiver's checksum must catch it).", Some("1.5")),
    // [estimators]
    k("estimators.run", "list of names, or [\"all\"]", "", "[] (none)", "names from `simnet estimators`", "The distributed estimators run beside each node's networked and independent filters.", Some("[\"nope\"]")),
    k("estimators.rounds", INT, "", "1", "1 to 100", "Consensus rounds per step, each with its sub-deadline inside the step.", Some("0")),
    k("estimators.kcf_gamma", NUM, "", "1 / (1 + the most in-neighbours of a node)", NONNEG, "KCF's consensus gain γ (Olfati-Saber 2009).", Some("-1")),
    k("estimators.hcmci_omega", NUM, "", "N, the number of nodes", POS, "HCMCI's ω (Battistelli et al. 2015).", Some("0")),
    k("estimators.<name>", "table", "", "empty", "the keys the registered scheme reads", "The own keys of a scheme a program registered (`[estimators.<name>]`), which it checks and reports by key (`estimators.<name>.<key>`); a table under any other name is refused.", None),
    k("estimators.sink", INT, "node id", "the first sensing node", "a sensing node's id", "The fusion center of both centralized schemes.", Some("999")),
    // [security]
    k("security.key_file", STR, "path", "none (unauthenticated)", "a key file of `simnet keygen`, relative to the topology file", "Every datagram sealed with this network key (AES-128-CCM, 8-byte tag).", Some("\"no-such.key\"")),
    k("security.auth", BOOL, "", "false", "true | false", "Authenticate with a key of the run's own (from its seed) where no key file is given.", None),
    // [medium]
    k("medium.kind", "pairwise | radio", "", "\"pairwise\"", "the words listed", "pairwise: every directed link decides alone by its [link] and [[edge]] rules. radio: one shared IEEE 802.15.4 channel (2.4 GHz O-QPSK, unslotted CSMA/CA, broadcast frames) between the nodes where the world places them; loss comes from distance, noise and contention, and the links must carry no rule of their own.", Some("\"ether\"")),
    k("medium.tx_dbm", NUM, "dBm", "0.0", "-50 to 30; radio only", "Every radio's transmit power (a CC2420's highest is 0 dBm).", Some("100")),
    k("medium.path_loss_exponent", NUM, "", "3.0", "0.5 to 10; radio only", "The log-distance path loss's exponent n: PL(d) = PL₀ + 10 n log₁₀(d / d₀) (ns-3's default).", Some("0")),
    k("medium.reference_m", NUM, "m", "1.0", "0.001 to 1000; radio only", "The log-distance reference distance d₀ (ns-3's default).", Some("0")),
    k("medium.reference_loss_db", NUM, "dB", "46.6777", "0 to 200; radio only", "The loss PL₀ at the reference distance (ns-3's default).", Some("-1")),
    k("medium.sensitivity_dbm", NUM, "dBm", "-95.0", "-106.58 to 0; radio only", "The receivers' sensitivity, which sets their noise figure as ns-3 does (a CC2420: −95 dBm, its datasheet) and the clear-channel assessment's threshold 10 dB above it.", Some("-120")),
    k("medium.ack", BOOL, "", "true", "true | false; radio only", "Unicasts (a message with one destination: a sealed run's per-link datagrams, centralized-net's to its sink) are acknowledged, and sent again when no ACK comes; broadcasts never are.", None),
    k("medium.max_frame_retries", INT, "", "3", "0 to 7; radio only", "How many times an unacknowledged unicast is sent again (macMaxFrameRetries) before it is given up.", Some("8")),
    k("medium.shadowing_db", NUM, "dB", "0.0 (none)", "0 to 20; radio only", "Log-normal shadowing's standard deviation σ: each pair's loss gains a normal variable in dB, the same both ways, constant while the pair stands still and decorrelating as it moves (Gudmundson 1991).", Some("-1")),
    k("medium.shadowing_decorrelation_m", NUM, "m", "8.306", "0.01 to 10000; radio only", "The distance moved over which the shadowing's correlation falls to 1/e (default: Gudmundson's 0.3 at 10 m).", Some("0")),
    // [generate]
    k("generate.graph", "ring | grid | complete | random-geometric", "", "required", "the words listed", "Nodes and edges from a graph instead of [[node]] and [[edge]] lists.", Some("\"tree\"")),
    k("generate.nodes", INT, "", "required", "1 to 10000 (2000 for complete and random-geometric)", "The number of nodes, ids 0 … n − 1.", Some("0")),
    k("generate.columns", INT, "", "the nearest square", "1 to nodes", "grid: its width.", Some("0")),
    k("generate.seed", INT, "", "1", "0 to 2⁶⁴ − 1", "random-geometric: the graph's own seed (the graph stays as the run seed changes).", Some("-1")),
    k("generate.naive_every", INT, "", "none", "≥ 2", "Every k-th node (ids k − 1, 2k − 1, …) is naive: an estimator without a sensor.", Some("1")),
    // [[node]]
    k("node[].id", INT, "", "its place in the list", "0 to 2³² − 2, unique", "The node's id in outputs and on the wire (2³² − 1 is the broadcast address).", Some("4294967295")),
    k("node[].role", "peer | sensor | estimator", "", "\"peer\"", "the words listed", "peer: senses and estimates; sensor: senses and sends; estimator: estimates only.", Some("\"boss\"")),
    k("node[].addr", STR, "host:port", "node<ID>:7000", "host:port, port 1 to 65535", "Where the node listens in a multi-host run (`simnet node`).", Some("\"nohost\"")),
    k("node[].sensor", "table", "", "[sensor]", "the keys of [sensor]", "This node's sensor, over the [sensor] defaults.", None),
    k("node[].position_m", "[x, y] or [x, y, z]", "m", "where a random-geometric graph was drawn (a square of 100 m), else the origin", "finite, within ±10⁶ m; linear models only", "Where the node stands (the world the medium sees); an IMU network's nodes ride the package instead.", Some("[1e9, 0]")),
    k("node[].lever_arm_m", "[x, y] or [x, y, z]", "m", "[0, 0, 0]", "finite, within ±10⁶ m; pose and attitude only", "Where the node's antenna is on the package, in the body frame (its IMU senses the package's origin).", Some("[1, 2, 3, 4]")),
    k("node[].imu_csv", STR, "path", "none (simulated)", "a recorded IMU file, relative to the topology file; pose and attitude only", "A recorded IMU instead of the simulated one.", Some("\"no-such.csv\"")),
    // [[edge]]
    k("edge[].nodes", "[id, id]", "", "required", "two different node ids", "The link's ends: both directions unless directed.", Some("[0, 0]")),
    k("edge[].directed", BOOL, "", "false", "true | false", "One direction only, from the first node to the second.", None),
    k("edge[].loss", "table", "", "[link] loss", "as link.loss", "This link's loss process.", None),
    k("edge[].delay_ms", NUM, "ms", "[link] delay_ms", "as link.delay_ms", "This link's delay.", Some("-1")),
    k("edge[].jitter_ms", NUM, "ms", "[link] jitter_ms", "as link.jitter_ms", "This link's jitter.", Some("-1")),
    k("edge[].jitter", "uniform | normal", "", "[link] jitter", "as link.jitter", "This link's jitter distribution.", Some("\"pareto\"")),
    k("edge[].duplicate", NUM, "", "[link] duplicate", PROB, "This link's duplication probability.", Some("1.5")),
    k("edge[].corrupt", NUM, "", "[link] corrupt", PROB, "This link's corruption probability.", Some("1.5")),
    // [[fault]]
    k("fault[].kind", "crash | link-down | partition", "", "required", "the words listed", "crash: the node stops (and comes back at restart_s, its filters re-initialised); link-down: a link carries nothing; partition: the nodes listed cannot talk to the others.", Some("\"meteor\"")),
    k("fault[].node", INT, "node id", "required (crash)", "a node's id", "crash: the node.", Some("999")),
    k("fault[].at_s", NUM, "s", "required (crash)", "≥ 0", "crash: when the node stops.", Some("-1")),
    k("fault[].restart_s", NUM, "s", "none (down to the end)", "after at_s", "crash: when the node comes back.", Some("-1")),
    k("fault[].link", "[id, id]", "", "required (link-down)", "two node ids joined by an edge", "link-down: the link.", Some("[0, 999]")),
    k("fault[].directed", BOOL, "", "false", "true | false", "link-down: from the first node to the second only.", None),
    k("fault[].nodes", "list of ids", "", "required (partition)", "some but not all nodes", "partition: the nodes cut off from the rest.", Some("[]")),
    k("fault[].start_s", NUM, "s", "required (link-down, partition)", "≥ 0", "When the window opens.", Some("-1")),
    k("fault[].end_s", NUM, "s", "required (link-down, partition)", "after start_s", "When the window closes.", Some("-1")),
    // [[attack]]
    k("attack[].kind", "forge | tamper | replay | flood | false-data", "", "required", "the words listed", "The adversary (see the Security chapter).", Some("\"jam\"")),
    k("attack[].target", INT, "node id", "required (forge, replay, flood)", "a node's id", "The node attacked from outside.", Some("999")),
    k("attack[].claim", INT, "node id", "required (forge, tamper, replay)", "a source the target hears", "The source whose datagrams are forged, changed or replayed.", Some("999")),
    k("attack[].node", INT, "node id", "required (false-data)", "a node's id", "false-data: the compromised node.", Some("999")),
    k("attack[].start_s", NUM, "s", "0.0", NONNEG, "When the attack starts.", Some("-1")),
    k("attack[].end_s", NUM, "s", "none (to the end)", "after start_s, finite", "When the attack stops.", Some("-1")),
    k("attack[].bias", "list of numbers", "unit of the measurement", "none", "one per measurement row, finite", "forge, tamper, false-data: what is added to each measurement row.", Some("[nan]")),
    k("attack[].ramp", "list of numbers", "unit of the measurement per s", "none", "one per measurement row, finite", "false-data: a bias that grows with time.", Some("[nan]")),
    k("attack[].delay_s", NUM, "s", "1.0", "≥ 0, at most the run's length", "replay: how old the replayed datagrams are.", Some("-1")),
    k("attack[].rate_hz", NUM, "Hz", "1000.0", "> 0, at most 1e6", "flood: datagrams per second.", Some("0")),
];

/// The chapter's tables: one per table of the file, each key with its type, unit, default, range and meaning.
pub fn markdown() -> String {
    use std::fmt::Write;
    let cell = |s: &str| {
        if s.is_empty() {
            "—".to_string()
        } else {
            crate::text::markdown_cell(s)
        }
    };
    let mut out = String::from(
        "<!-- generated by `cargo xtask docs` from simnet::scenario::schema::KEYS: do not edit by hand -->\n",
    );
    let mut section = "";
    for key in KEYS {
        let table = match key.key.split_once('.') {
            Some((t, _)) => t,
            None if ["sensor", "link"].contains(&key.key) => key.key,
            None => "the file",
        };
        if table != section {
            section = table;
            let heading = match table {
                "the file" => "The file".to_string(),
                t if t.ends_with("[]") => format!("`[[{}]]`", t.trim_end_matches("[]")),
                t => format!("`[{t}]`"),
            };
            let _ = write!(
                out,
                "\n#### {heading}\n\n| key | type | unit | default | range | meaning |\n|---|---|---|---|---|---|\n"
            );
        }
        let _ = writeln!(
            out,
            "| `{}` | {} | {} | {} | {} | {} |",
            key.key,
            cell(key.kind),
            cell(key.unit),
            cell(key.default),
            cell(key.range),
            cell(key.means)
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Scenario;

    /// The fields a table of the file accepts, as the parser names them when it meets one it does not know.
    fn fields(toml: &str) -> Vec<String> {
        let Err(e) = ::toml::from_str::<super::super::toml::RawTopology>(toml) else {
            panic!("an unknown key is accepted in {toml}");
        };
        let text = e.message().to_string();
        let list = text.split("expected").nth(1).unwrap_or_else(|| panic!("{text}"));
        list.split('`').skip(1).step_by(2).map(String::from).collect()
    }

    /// Every key the file format accepts is in the table, and every key in the table is one the format accepts.
    #[test]
    fn the_table_names_every_key_of_the_file_and_no_other() {
        const U: &str = "zz_unknown = 1";
        let tables: [(&str, String); 17] = [
            ("", format!("{U}\n")),
            ("sim", format!("[sim]\n{U}\n")),
            ("model", format!("[model]\n{U}\n")),
            ("consensus", format!("[consensus]\n{U}\n")),
            ("consensus.lmi", format!("[consensus.lmi]\n{U}\n")),
            ("sensor", format!("[sensor]\n{U}\n")),
            ("link", format!("[link]\n{U}\n")),
            ("link.loss", format!("[link.loss]\n{U}\n")),
            ("estimators", format!("[estimators]\n{U}\n")),
            ("security", format!("[security]\n{U}\n")),
            ("medium", format!("[medium]\n{U}\n")),
            ("generate", format!("[generate]\ngraph = \"ring\"\n{U}\n")),
            ("node[]", format!("[[node]]\n{U}\n")),
            ("node[].sensor", format!("[[node]]\n[node.sensor]\n{U}\n")),
            ("edge[]", format!("[[edge]]\nnodes = [0, 1]\n{U}\n")),
            ("fault[]", format!("[[fault]]\nkind = \"crash\"\n{U}\n")),
            ("attack[]", format!("[[attack]]\nkind = \"forge\"\n{U}\n")),
        ];
        let mut accepted = Vec::new();
        for (table, toml) in &tables {
            for f in fields(toml) {
                let key = if table.is_empty() { f } else { format!("{table}.{f}") };
                // [node.sensor] has [sensor]'s keys: the table documents them once.
                if key.starts_with("node[].sensor.") {
                    assert!(
                        KEYS.iter().any(|k| k.key == key.replacen("node[].", "", 1)),
                        "{key} is not in [sensor]"
                    );
                    continue;
                }
                // A table of the file is documented by its keys.
                let table_of_file = tables.iter().any(|(t, _)| t.trim_end_matches("[]") == key);
                if !table_of_file {
                    accepted.push(key);
                }
            }
        }
        for key in &accepted {
            assert!(
                KEYS.iter().any(|k| k.key == *key),
                "`{key}` is accepted but not documented"
            );
        }
        // A table named by a registry (`[estimators.<name>]`) is not among the parser's fields: the parser takes a
        // table of any name there, and the validator refuses it, naming it, unless a program registered that name.
        let named = ::toml::from_str::<super::super::toml::RawTopology>("[estimators.zz]\nq = 1\n");
        assert!(named.is_ok(), "{named:?}");
        let base_file = Scenario::from_toml(&base("estimators.run"), "base.toml").unwrap();
        for name in ["zz", "kcf"] {
            let refused = base_file
                .set(&format!("estimators.{name}.q"), ::toml::Value::Integer(1))
                .unwrap_err();
            assert!(refused.to_string().contains(&format!("estimators.{name}")), "{refused}");
        }
        for k in KEYS {
            let table_itself = tables.iter().any(|(t, _)| *t == k.key) || k.key == "estimators.<name>";
            assert!(
                table_itself || accepted.contains(&k.key.to_string()),
                "`{}` is documented but not accepted",
                k.key
            );
        }
    }

    /// A small file of each model with every table present, in which any key can be set.
    fn base(key: &str) -> String {
        // [generate] replaces the node and edge lists: its keys are tried on a file of their own.
        if key.starts_with("generate.") {
            let graph = if key == "generate.seed" {
                "random-geometric"
            } else {
                "grid"
            };
            return format!("name = \"base\"\n[sim]\nduration_s = 1.0\n[generate]\ngraph = \"{graph}\"\nnodes = 6\n");
        }
        let model = if ["model.r_acc", "model.r_mag", "model.mag_field"].contains(&key) {
            "kind = \"attitude\"\n"
        } else if [
            "model.a",
            "model.c",
            "model.q",
            "model.r",
            "model.x0",
            "model.p0",
            "model.observe",
        ]
        .contains(&key)
        {
            "kind = \"linear\"\na = [[1.0]]\nc = [[1.0]]\nq = [[1.0]]\nr = [[1.0]]\n"
        } else {
            "kind = \"pose\"\n"
        };
        let loss = if ["link.loss.one_minus_h", "link.loss.one_minus_k"].contains(&key) {
            "model = \"gilbert-elliott\"\np = 0.1\nr = 0.5\n"
        } else {
            ""
        };
        let fault = match key {
            "fault[].link" | "fault[].directed" => "kind = \"link-down\"\nlink = [0, 1]\nstart_s = 0.2\nend_s = 0.6\n",
            "fault[].nodes" | "fault[].start_s" | "fault[].end_s" => {
                "kind = \"partition\"\nnodes = [1]\nstart_s = 0.2\nend_s = 0.6\n"
            }
            _ => "kind = \"crash\"\nnode = 2\nat_s = 0.5\n",
        };
        let rows = if model.contains("linear") { 1 } else { 6 };
        let attack = match key {
            "attack[].delay_s" => "kind = \"replay\"\ntarget = 0\nclaim = 1\nstart_s = 0.5\n".to_string(),
            "attack[].rate_hz" => "kind = \"flood\"\ntarget = 0\nstart_s = 0.5\n".to_string(),
            _ => format!(
                "kind = \"forge\"\ntarget = 0\nclaim = 1\nstart_s = 0.5\nbias = [{}]\n",
                vec!["0.0"; rows].join(", ")
            ),
        };
        // A radio's keys are tried on a radio.
        let medium = if key.starts_with("medium.") && key != "medium.kind" {
            "[medium]\nkind = \"radio\"\n"
        } else {
            ""
        };
        let sim = if model.contains("linear") {
            "[sim]\nduration_s = 1.0\n"
        } else {
            "[sim]\nduration_s = 1.0\ntrajectory = \"spiral\"\n"
        };
        format!(
            "name = \"base\"\n{sim}[model]\n{model}[consensus]\n[consensus.lmi]\n[sensor]\n[link]\n[link.loss]\n{loss}\
             [estimators]\n[security]\n{medium}\
             [[node]]\nid = 0\n[[node]]\nid = 1\n[node.sensor]\n[[node]]\nid = 2\n\
             [[edge]]\nnodes = [0, 1]\n[[edge]]\nnodes = [1, 2]\n[[edge]]\nnodes = [2, 0]\n\
             [[fault]]\n{fault}\
             [[attack]]\n{attack}"
        )
    }

    /// `key` in the base file as set by `simnet --set`: a list entry by its first index.
    fn path(key: &str) -> String {
        key.replace("[]", "[0]")
    }

    /// The value at `key` (`node[0].sensor.gyro_noise`) in a file, if it gives one.
    fn lookup<'a>(doc: &'a ::toml::Value, key: &str) -> Option<&'a ::toml::Value> {
        key.split('.').try_fold(doc, |cur, part| match part.split_once('[') {
            None => cur.get(part),
            Some((name, i)) => cur.get(name)?.get(i.trim_end_matches(']').parse::<usize>().ok()?),
        })
    }

    /// Each key's refused value is refused, with a problem naming the key.
    #[test]
    fn a_value_out_of_range_is_refused_naming_its_key() {
        let mut wrong = Vec::new();
        for k in KEYS {
            let Some(bad) = k.refused else { continue };
            let (text, key) = (base(k.key), path(k.key));
            let s = Scenario::from_toml(&text, "base.toml").unwrap_or_else(|e| panic!("{}: {e}", k.key));
            match s.set(&key, super::super::keys::parse_value(bad)) {
                Ok(_) => wrong.push(format!("`{key} = {bad}` was accepted")),
                Err(e) if !e.to_string().contains(&key) => wrong.push(format!("`{key} = {bad}`: {e}")),
                Err(_) => {}
            }
        }
        assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    }

    /// Giving a key its documented default runs exactly as leaving it out.
    #[test]
    fn a_documented_default_is_the_default() {
        let run = |s: &Scenario| {
            let mut summary = crate::Sim::new(s).and_then(|sim| sim.run()).expect("runs").summary();
            summary.reproducible();
            if let Some(settings) = summary.settings.as_mut() {
                settings.scenario.clear();
                settings.scenario_sha256.clear();
            }
            summary
        };
        let mut checked = 0;
        let mut wrong = Vec::new();
        for k in KEYS {
            // A default in words (a rule, "required", "none") is not one value to give.
            let Ok(value) = ::toml::from_str::<::toml::Table>(&format!("v = {}", k.default)) else {
                continue;
            };
            let value = value["v"].clone();
            let key = path(k.key);
            let s = Scenario::from_toml(&base(k.key), "base.toml").expect("the base file is valid");
            // A key the base file gives itself (its short duration, its fault) cannot be left out.
            if lookup(&::toml::from_str(&s.to_toml()).expect("TOML"), &key).is_some() {
                continue;
            }
            // Written into the file, as a user would (`--set` refuses some keys, such as the seed).
            let mut doc: ::toml::Value = ::toml::from_str(&s.to_toml()).expect("TOML");
            super::super::keys::put(&mut doc, &key, value).expect("the key has a place in the file");
            let given = Scenario::from_toml(&::toml::to_string(&doc).expect("TOML"), "base.toml")
                .unwrap_or_else(|e| panic!("`{key} = {}`: {e}", k.default));
            if run(&s) != run(&given) {
                wrong.push(format!("{key} = {}", k.default));
            }
            checked += 1;
        }
        assert!(
            wrong.is_empty(),
            "leaving these out is not the same as giving them: {wrong:?}"
        );
        assert!(checked > 40, "only {checked} defaults are values");
    }

    #[test]
    fn the_chapter_has_a_row_per_key() {
        let md = markdown();
        assert_eq!(md.lines().filter(|l| l.starts_with("| `")).count(), KEYS.len());
    }
}
