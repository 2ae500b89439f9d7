//! `simnet._simnet`: the native half of the Python package. It holds scenarios, runs them over UDP with the tables
//! kept in memory, runs campaigns into a directory and computes covariance bounds; `simnet/__init__.py` turns what
//! it returns into pandas frames and numpy arrays.
//!
//! Every long call releases the GIL and waits in slices of 50 ms, between which it checks for Ctrl-C (which stops
//! the run, keeping what it did) and reports progress.

use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration;

use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyBytes, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use simnet::analysis::bounds as study;
use simnet::campaign::{self, Axis, CampaignError, Plan, PlanFile, Store};
use simnet::estimate::bounds::FixedPoint;
use simnet::estimators::Kind;
use simnet::net::{self, RunOptions};
use simnet::report::trace::TraceWriter;
use simnet::scenario::{builtin, FlagError, Flags, Scenario, ScenarioError as Invalid};

create_exception!(
    _simnet,
    ScenarioError,
    PyValueError,
    "A scenario or option simnet refuses. `key` names the first key at fault (None when the whole file is), \
     `problems` lists every (key, message), and str() is what the command line prints."
);

/// How often a waiting call looks at Ctrl-C and reports progress.
const POLL: Duration = Duration::from_millis(50);

fn raise(py: Python<'_>, message: String, key: Option<String>, problems: Vec<(String, String)>) -> PyErr {
    let err = ScenarioError::new_err(message.clone());
    let v = err.value(py);
    // Setting attributes on a fresh exception cannot fail.
    let _ = v.setattr("message", message);
    let _ = v.setattr("key", key);
    let _ = v.setattr("problems", problems);
    err
}

fn scenario_error(py: Python<'_>, e: &Invalid) -> PyErr {
    let problems: Vec<(String, String)> = match e {
        Invalid::Invalid { problems, .. } => problems.iter().map(|p| (p.key.clone(), p.message.clone())).collect(),
        _ => Vec::new(),
    };
    raise(py, e.to_string(), problems.first().map(|p| p.0.clone()), problems)
}

/// An option error keyed by its Python name (`loss_model`); the message is the command line's.
fn flag_error(py: Python<'_>, e: FlagError) -> PyErr {
    match e {
        FlagError::Scenario(e) => scenario_error(py, &e),
        FlagError::Option { option, .. } => {
            let key = option.replace('-', "_");
            raise(py, e.to_string(), Some(key.clone()), vec![(key, e.to_string())])
        }
    }
}

fn option_error(py: Python<'_>, key: &str, message: String) -> PyErr {
    raise(
        py,
        message.clone(),
        Some(key.to_string()),
        vec![(key.to_string(), message)],
    )
}

/// A plain Python value (bool, int, float, str, list, tuple, dict) as the TOML value a file would hold.
fn to_toml(py: Python<'_>, key: &str, v: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        if let Ok(i) = v.extract::<i64>() {
            return Ok(toml::Value::Integer(i));
        }
        // TOML's integers stop at 2^63 − 1: a larger seed goes as its digits (RUN_OPTIONS reads them).
        return v
            .extract::<u64>()
            .map(|u| toml::Value::String(u.to_string()))
            .map_err(|_| option_error(py, key, format!("`{key}`: integer out of range")));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if v.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(v.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        let mut t = toml::map::Map::new();
        for (k, x) in d.iter() {
            let k: String = k.extract()?;
            let inner = format!("{key}.{k}");
            t.insert(k, to_toml(py, &inner, &x)?);
        }
        return Ok(toml::Value::Table(t));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = v.extract()?;
        return items
            .iter()
            .enumerate()
            .map(|(i, x)| to_toml(py, &format!("{key}[{i}]"), x))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    // NumPy's scalars: an integer has __index__, a float __float__.
    if v.hasattr("__index__")? {
        if let Ok(i) = v.extract::<i64>() {
            return Ok(toml::Value::Integer(i));
        }
    }
    if v.hasattr("__float__")? {
        if let Ok(x) = v.extract::<f64>() {
            return Ok(toml::Value::Float(x));
        }
    }
    Err(PyTypeError::new_err(format!(
        "`{key}`: a {} is not a scenario value (give a bool, number, string, list or dict)",
        v.get_type().name()?
    )))
}

/// The options of `simnet run` by their Python names; any other name is a scenario key (`__` for `.`).
fn flags_of(py: Python<'_>, opts: &Bound<'_, PyDict>) -> PyResult<Flags> {
    let mut f = Flags::default();
    for (k, v) in opts.iter() {
        let key: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        if key == "set" {
            let d = v
                .cast::<PyDict>()
                .map_err(|_| PyTypeError::new_err("`set`: expected a dict of scenario keys and values"))?;
            for (k, x) in d.iter() {
                let k: String = k.extract()?;
                let value = to_toml(py, &k, &x)?;
                f.set.push((k, value));
            }
            continue;
        }
        // An option of `simnet run` by its name (simnet::scenario::RUN_OPTIONS), read as the command line reads it.
        let value = to_toml(py, &key, &v)?;
        match f.set_option(&key, &value) {
            Some(r) => r.map_err(|e| flag_error(py, e))?,
            None => f.set.push((key.replace("__", "."), value)),
        }
    }
    Ok(f)
}

/// `"all"`, `"kcf,icf"` or `["kcf", "icf"]` as estimator kinds.
fn kinds(py: Python<'_>, v: &Bound<'_, PyAny>) -> PyResult<Vec<Kind>> {
    let mut f = Flags::default();
    let value = to_toml(py, "estimators", v)?;
    match f.set_option("estimators", &value) {
        Some(Ok(())) => Ok(f.estimators.unwrap_or_default()),
        Some(Err(e)) => Err(flag_error(py, e)),
        None => unreachable!("estimators is an option"),
    }
}

/// A validated scenario: every run of it is reproducible from its seed.
#[pyclass(name = "Scenario", module = "simnet._simnet", frozen)]
struct PyScenario {
    inner: Arc<Scenario>,
}

impl PyScenario {
    fn of(py: Python<'_>, r: Result<Scenario, Invalid>) -> PyResult<PyScenario> {
        r.map(|s| PyScenario { inner: Arc::new(s) })
            .map_err(|e| scenario_error(py, &e))
    }
}

#[pymethods]
impl PyScenario {
    /// A path, then `./topologies/NAME.toml`, then a built-in (as `--topology`).
    #[staticmethod]
    fn resolve(py: Python<'_>, name: &str) -> PyResult<PyScenario> {
        PyScenario::of(py, Scenario::resolve(name))
    }

    /// A built-in topology only.
    #[staticmethod]
    fn builtin(py: Python<'_>, name: &str) -> PyResult<PyScenario> {
        match builtin::get(name) {
            Some(text) => PyScenario::of(py, Scenario::from_toml(text, &format!("builtin:{name}"))),
            None => {
                let known: Vec<&str> = builtin::ALL.iter().map(|(n, _)| *n).collect();
                Err(option_error(
                    py,
                    "topology",
                    format!("`{name}` is not a built-in topology (known: {})", known.join(", ")),
                ))
            }
        }
    }

    /// A scenario from TOML text; `source` names it in errors.
    #[staticmethod]
    #[pyo3(signature = (text, source = "<string>"))]
    fn from_toml(py: Python<'_>, text: &str, source: &str) -> PyResult<PyScenario> {
        PyScenario::of(py, Scenario::from_toml(text, source))
    }

    /// A scenario read from a topology file.
    #[staticmethod]
    fn from_path(py: Python<'_>, path: &str) -> PyResult<PyScenario> {
        PyScenario::of(py, Scenario::from_path(std::path::Path::new(path)))
    }

    /// This scenario with `simnet run`'s options and scenario keys applied, validated as a whole.
    fn with_options(&self, py: Python<'_>, options: &Bound<'_, PyDict>) -> PyResult<PyScenario> {
        let flags = flags_of(py, options)?;
        flags
            .apply(&self.inner)
            .map(|s| PyScenario { inner: Arc::new(s) })
            .map_err(|e| flag_error(py, e))
    }

    /// The TOML this scenario would be read from.
    fn to_toml(&self) -> String {
        self.inner.to_toml()
    }

    /// What the validator would warn about.
    fn warnings(&self) -> Vec<String> {
        self.inner.warnings()
    }

    #[getter]
    fn name(&self) -> String {
        self.inner.name().to_string()
    }
    #[getter]
    fn description(&self) -> String {
        self.inner.description().to_string()
    }
    #[getter]
    fn source(&self) -> String {
        self.inner.source().to_string()
    }
    #[getter]
    fn model(&self) -> String {
        self.inner.model().kind().to_string()
    }
    #[getter]
    fn nodes(&self) -> usize {
        self.inner.nodes().len()
    }
    #[getter]
    fn links(&self) -> usize {
        self.inner.links().len()
    }
    #[getter]
    fn steps(&self) -> u64 {
        self.inner.sim().steps()
    }
    #[getter]
    fn duration_s(&self) -> f64 {
        self.inner.sim().duration_s
    }
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.inner.sim().rate_hz
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.inner.sim().seed
    }
    #[getter]
    fn estimators(&self) -> Vec<String> {
        self.inner
            .estimators()
            .run
            .iter()
            .map(|k| k.name().to_string())
            .collect()
    }
    /// Every node's position at time `t` (s), in metres, as (id, x, y, z) in node order: an IMU network's nodes
    /// ride the package along `sim.trajectory`, a linear system's stand where the scenario puts them.
    #[pyo3(signature = (t = 0.0))]
    fn positions(&self, t: f64) -> Vec<(u32, f64, f64, f64)> {
        let world = self.inner.world();
        self.inner
            .nodes()
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let p = world.position(i, simnet::time::Time::from_secs(t));
                (n.id, p.x, p.y, p.z)
            })
            .collect()
    }

    /// The SHA-256 of the resolved scenario: two scenarios with one digest make the same runs.
    #[getter]
    fn digest(&self) -> String {
        self.inner.digest()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scenario({:?}: {} nodes, {} model, {} s at {} Hz, seed {})",
            self.inner.name(),
            self.inner.nodes().len(),
            self.inner.model().kind(),
            self.inner.sim().duration_s,
            self.inner.sim().rate_hz,
            self.inner.sim().seed
        )
    }
}

/// A table written in memory while the run goes.
#[derive(Clone, Default)]
struct Buf(Arc<Mutex<Vec<u8>>>);

impl Write for Buf {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0
            .lock()
            .map_err(|_| std::io::Error::other("table lock poisoned"))?
            .extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Buf {
    fn writer(&self) -> Box<dyn Write + Send> {
        Box::new(std::io::BufWriter::with_capacity(1 << 16, self.clone()))
    }
    fn bytes<'py>(&self, py: Python<'py>) -> Bound<'py, PyBytes> {
        let v = self.0.lock().map(|v| v.clone()).unwrap_or_default();
        PyBytes::new(py, &v)
    }
}

/// Wait for `rx` with the GIL released, in slices: between them Ctrl-C sets `stop` (the work winds down and its
/// result still comes), and `progress(done, total)` is called. `Ok((result, interrupted))`; a progress callback
/// that raises stops the work and its error is raised once the work ended.
fn wait<T: Send>(
    py: Python<'_>,
    rx: mpsc::Receiver<T>,
    stop: &AtomicBool,
    done: &AtomicU64,
    total: u64,
    progress: Option<&Bound<'_, PyAny>>,
) -> PyResult<(T, bool)> {
    let rx = Mutex::new(rx);
    let mut interrupted = false;
    let mut failed: Option<PyErr> = None;
    loop {
        let got = py.detach(|| match rx.lock() {
            Ok(r) => r.recv_timeout(POLL),
            Err(_) => Err(mpsc::RecvTimeoutError::Disconnected),
        });
        match got {
            Ok(v) => {
                if let (Some(cb), None, false) = (progress, &failed, interrupted) {
                    // The work has ended: a callback that raises now has its error raised.
                    if let Err(e) = cb.call1((done.load(Ordering::Relaxed), total)) {
                        failed = Some(e);
                    }
                }
                return match failed {
                    Some(e) => Err(e),
                    None => Ok((v, interrupted)),
                };
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(PyRuntimeError::new_err(
                    "the simnet worker thread stopped without a result",
                ))
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if !interrupted && py.check_signals().is_err() {
            interrupted = true;
            stop.store(true, Ordering::SeqCst);
        }
        if let (Some(cb), None) = (progress, &failed) {
            if let Err(e) = cb.call1((done.load(Ordering::Relaxed), total)) {
                stop.store(true, Ordering::SeqCst);
                // Ctrl-C while the callback ran is Ctrl-C.
                if e.is_instance_of::<PyKeyboardInterrupt>(py) {
                    interrupted = true;
                } else {
                    failed = Some(e);
                }
            }
        }
    }
}

/// Run a scenario over UDP sockets on loopback (the virtual clock, as `simnet run`): the summary as
/// `summary.json` text and the tables as CSV bytes.
#[pyfunction]
#[pyo3(signature = (scenario, progress = None, tables = true))]
fn run<'py>(
    py: Python<'py>,
    scenario: &PyScenario,
    progress: Option<Bound<'py, PyAny>>,
    tables: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let topo = scenario.inner.clone();
    let (trace, measurements, estimators) = (Buf::default(), Buf::default(), Buf::default());
    let with_estimators = !topo.estimators().run.is_empty();
    let obs = topo.model().get().observation();
    let mut writer = TraceWriter::for_topology(&topo)
        .to_writer(trace.writer())
        .with_measurements(measurements.writer(), obs);
    if with_estimators {
        writer = writer.with_estimators(estimators.writer());
    }
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let d = done.clone();
    let opts = RunOptions {
        // Without tables no row is made: the run costs what `simnet --json` does.
        trace: tables.then_some(writer),
        progress: Some(Arc::new(move |n, _| d.store(n, Ordering::Relaxed))),
        ..Default::default()
    };
    let (tx, rx) = mpsc::channel();
    let (t, s) = (topo.clone(), stop.clone());
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get()).max(2);
    std::thread::spawn(move || {
        let r = net::run_blocking(t, opts, s, threads).map(|mut out| {
            let rows = out.trace.take().map(TraceWriter::finish).transpose();
            (out, rows)
        });
        let _ = tx.send(r);
    });
    let (result, interrupted) = wait(py, rx, &stop, &done, topo.sim().steps(), progress.as_ref())?;
    let (out, rows) = result.map_err(|e| match e {
        net::NetError::Scenario(e) => scenario_error(py, &e),
        e => PyRuntimeError::new_err(e.to_string()),
    })?;
    rows.map_err(|e| PyRuntimeError::new_err(format!("writing the trace: {e}")))?;
    let summary = out
        .summary_beside_clean()
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    let mut links = Vec::new();
    simnet::report::summary::write_links(&mut links, &summary.links)
        .map_err(|e| PyRuntimeError::new_err(format!("writing links: {e}")))?;
    let d = PyDict::new(py);
    d.set_item("summary", summary.to_json())?;
    d.set_item("trace", tables.then(|| trace.bytes(py)))?;
    d.set_item("links", PyBytes::new(py, &links))?;
    d.set_item("measurements", tables.then(|| measurements.bytes(py)))?;
    d.set_item("estimators", (tables && with_estimators).then(|| estimators.bytes(py)))?;
    d.set_item("keyboard_interrupt", interrupted)?;
    Ok(d)
}

fn campaign_error(py: Python<'_>, e: CampaignError) -> PyErr {
    match e {
        CampaignError::Scenario(e) => scenario_error(py, &e),
        e if e.is_usage() => option_error(py, "out", e.to_string()),
        e => PyRuntimeError::new_err(e.to_string()),
    }
}

/// A campaign as `simnet sweep` runs it: `axes` (`KEY=V1,V2` or `KEY=START:END:STEP`) × seeds 1 … `seeds`, on
/// every core, into `out` (resumable: runs already there are kept). The files written, and what ran.
#[pyfunction]
#[pyo3(signature = (scenario, axes, out, seeds = 10, estimators = None, rounds = None, duration = None,
    transport = "memory", progress = None))]
#[allow(clippy::too_many_arguments)]
fn sweep<'py>(
    py: Python<'py>,
    scenario: &PyScenario,
    axes: Vec<String>,
    out: std::path::PathBuf,
    seeds: u64,
    estimators: Option<Bound<'py, PyAny>>,
    rounds: Option<u64>,
    duration: Option<f64>,
    transport: &str,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    if !(1..=100_000).contains(&seeds) {
        return Err(option_error(
            py,
            "seeds",
            format!("--seeds: must be 1 to 100000, got {seeds}"),
        ));
    }
    let udp = match transport {
        "memory" => false,
        "udp" => true,
        t => {
            return Err(option_error(
                py,
                "transport",
                format!("--transport: `{t}` is not memory or udp"),
            ))
        }
    };
    if axes.is_empty() {
        return Err(option_error(
            py,
            "set",
            "--set: a sweep needs at least one key and its values".into(),
        ));
    }
    let mut command = vec!["simnet.sweep (Python)".to_string(), scenario.inner.name().to_string()];
    for a in &axes {
        command.extend(["--set".to_string(), a.clone()]);
    }
    command.extend(["--seeds".to_string(), seeds.to_string()]);
    let axes: Vec<Axis> = axes
        .iter()
        .map(|s| {
            Axis::parse(s).map_err(|e| option_error(py, s.split('=').next().unwrap_or(s).trim(), format!("--set {e}")))
        })
        .collect::<PyResult<_>>()?;
    let kinds = estimators.map(|e| kinds(py, &e)).transpose()?;
    // The range check of --rounds, as the CLI makes it.
    Flags {
        rounds,
        ..Flags::default()
    }
    .overrides()
    .map_err(|e| flag_error(py, e))?;
    let base = campaign::sweep_base(&scenario.inner, kinds, rounds, duration).map_err(|e| scenario_error(py, &e))?;
    let plan = Plan::new(base, axes, seeds).map_err(|e| scenario_error(py, &e))?;
    let store = Store::open(&out, &PlanFile::of(&plan)).map_err(|e| campaign_error(py, e))?;
    let runs = plan.runs();
    let total = runs.len() as u64;
    let stop = Arc::new(AtomicBool::new(false));
    let done = Arc::new(AtomicU64::new(0));
    let (tx, rx) = mpsc::channel();
    let who = campaign::Runner {
        shard: "all".into(),
        command,
        transport: transport.into(),
    };
    let (campaign::Executed { ran, finished }, interrupted) = std::thread::scope(|scope| -> PyResult<_> {
        let (plan, store, runs, stop2, done2) = (&plan, &store, &runs, stop.clone(), done.clone());
        scope.spawn(move || {
            let run_one = |s: &Scenario| {
                if udp {
                    net::run_blocking(Arc::new(s.clone()), RunOptions::default(), stop2.clone(), 1)
                        .map(|r| r.summary())
                        .map_err(|e| e.to_string())
                } else {
                    campaign::in_memory(s)
                }
            };
            let tick = || {
                done2.fetch_add(1, Ordering::Relaxed);
            };
            let _ = tx.send(campaign::execute(plan, runs, store, who, &run_one, &tick, &stop2));
        });
        wait(py, rx, &stop, &done, total, progress.as_ref())
    })?;
    let d = PyDict::new(py);
    d.set_item("dir", out.display().to_string())?;
    d.set_item("runs", total)?;
    d.set_item("ran", ran.ran)?;
    d.set_item("kept", ran.kept)?;
    d.set_item("stopped", ran.stopped)?;
    let failed: Vec<(String, String, u64, String)> = ran
        .failed
        .iter()
        .map(|(r, why)| (r.key.clone(), plan.describe(r.point), r.seed, why.clone()))
        .collect();
    d.set_item("failed", failed)?;
    d.set_item("keyboard_interrupt", interrupted)?;
    match finished {
        Ok(f) => d.set_item("files", f.files)?,
        // Runs missing (stopped or failed): the files are written when a later call completes the campaign.
        Err(CampaignError::Missing { .. }) => d.set_item("files", Vec::<String>::new())?,
        Err(e) => return Err(campaign_error(py, e)),
    }
    Ok(d)
}

fn fixed_point(f: &FixedPoint) -> (f64, Option<Vec<Vec<f64>>>) {
    match f {
        FixedPoint::Converged(m) => (
            m.trace(),
            Some(
                (0..m.nrows())
                    .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
                    .collect(),
            ),
        ),
        FixedPoint::Diverged => (f64::INFINITY, None),
        FixedPoint::Undecided => (f64::NAN, None),
    }
}

fn matrix(py: Python<'_>, name: &str, rows: Vec<Vec<f64>>) -> PyResult<nalgebra::DMatrix<f64>> {
    let c = rows.first().map_or(0, |r| r.len());
    if rows.is_empty() || c == 0 || rows.iter().any(|r| r.len() != c) {
        return Err(option_error(
            py,
            name,
            format!("{name}: rows must be non-empty and of equal length"),
        ));
    }
    Ok(nalgebra::DMatrix::from_fn(rows.len(), c, |i, j| rows[i][j]))
}

fn bounds_error(py: Python<'_>, e: study::BoundsError) -> PyErr {
    match e {
        study::BoundsError::Scenario(e) => scenario_error(py, &e),
        e => PyValueError::new_err(e.to_string()),
    }
}

/// Sinopoli et al.'s covariance bounds at each arrival rate of `lams`, for the matrices given or, with
/// `scenario`, its linear model; `measure` also runs the scenario at each rate.
#[pyfunction]
#[pyo3(signature = (lams, a = None, c = None, q = None, r = None, scenario = None, measure = false))]
#[allow(clippy::too_many_arguments)]
fn bounds<'py>(
    py: Python<'py>,
    lams: Vec<f64>,
    a: Option<Vec<Vec<f64>>>,
    c: Option<Vec<Vec<f64>>>,
    q: Option<Vec<Vec<f64>>>,
    r: Option<Vec<Vec<f64>>>,
    scenario: Option<&PyScenario>,
    measure: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let sys = match (scenario, a, c, q, r) {
        (Some(s), None, None, None, None) => study::System::of(&s.inner).map_err(|e| bounds_error(py, e))?,
        (None, Some(a), Some(c), Some(q), Some(r)) => study::System::new(
            matrix(py, "A", a)?,
            matrix(py, "C", c)?,
            matrix(py, "Q", q)?,
            matrix(py, "R", r)?,
            "simnet.bounds",
        )
        .map_err(|e| bounds_error(py, e))?,
        _ => {
            return Err(PyTypeError::new_err(
                "bounds: give A, C, Q and R, or a scenario with a linear model",
            ))
        }
    };
    if measure && scenario.is_none() {
        return Err(PyTypeError::new_err("bounds: measure=True runs a scenario: give one"));
    }
    for &l in &lams {
        if !(0.0..=1.0).contains(&l) {
            return Err(option_error(
                py,
                "lam",
                format!("lam: an arrival rate is in [0, 1], got {l}"),
            ));
        }
    }
    let st = study::stability(&sys).map_err(|e| bounds_error(py, e))?;
    let scen = scenario.map(|s| s.inner.clone());
    let rows = py.detach(|| {
        lams.iter()
            .map(|&l| {
                let (s, v) = study::at(&sys, l)?;
                let m = match (&scen, measure) {
                    (Some(t), true) => study::measure(t, l)?,
                    _ => None,
                };
                Ok((l, s, v, m))
            })
            .collect::<Result<Vec<_>, study::BoundsError>>()
    });
    let rows = rows.map_err(|e| bounds_error(py, e))?;
    let d = PyDict::new(py);
    d.set_item("rho", st.rho)?;
    d.set_item("lambda_min", st.lambda_min)?;
    d.set_item("lambda_bar", st.critical.value())?;
    d.set_item("lambda_bar_interval", (st.critical.lo, st.critical.hi))?;
    let out = PyList::empty(py);
    for (l, s, v, m) in rows {
        let (ts, sm) = fixed_point(&s);
        let (tv, vm) = fixed_point(&v);
        out.append((l, ts, tv, sm, vm, m))?;
    }
    d.set_item("rows", out)?;
    Ok(d)
}

/// A recording studied by `simnet attitude`: its JSON text and `attitude.csv` bytes.
#[pyfunction]
#[pyo3(signature = (file, reference = None, columns = None, units = None, rate = None, gates = None,
                    calibrate_mag = false, compare = Vec::new()))]
#[allow(clippy::too_many_arguments)]
fn attitude<'py>(
    py: Python<'py>,
    file: std::path::PathBuf,
    reference: Option<std::path::PathBuf>,
    columns: Option<String>,
    units: Option<String>,
    rate: Option<f64>,
    gates: Option<String>,
    calibrate_mag: bool,
    compare: Vec<(String, std::path::PathBuf)>,
) -> PyResult<Bound<'py, PyDict>> {
    use simnet::analysis::attitude::{study, Gates, GATES};
    use simnet::imu_csv::layout;
    let bad = |key: &str, m: String| option_error(py, key, m);
    let o = layout::ReadOptions {
        columns: columns
            .map(|c| layout::parse_columns(&c))
            .transpose()
            .map_err(|e| bad("columns", format!("--columns: {e}")))?
            .unwrap_or_default(),
        units: units
            .map(|u| layout::parse_units(&u))
            .transpose()
            .map_err(|e| bad("units", format!("--units: {e}")))?
            .unwrap_or_default(),
        rate_hz: match rate {
            Some(r) if !(r.is_finite() && r > 0.0) => {
                return Err(bad("rate", format!("--rate: must be a positive number, got {r}")))
            }
            r => r,
        },
    };
    let gates = match gates {
        Some(g) => Gates::parse(&g).map_err(|e| bad("gates", format!("--gates: {e}")))?,
        None => GATES,
    };
    let read = |p: &std::path::Path| {
        let shown = p.display().to_string();
        simnet::input::read_text(p, simnet::input::MAX_TABLE)
            .map(|t| (t, shown.clone()))
            .map_err(|e| bad("file", format!("{shown}: cannot read: {e}")))
    };
    let (text, name) = read(&file)?;
    let reference = reference.as_deref().map(read).transpose()?;
    let compared = compare
        .iter()
        .map(|(n, p)| read(p).map(|(text, file)| (n.as_str(), text, file)))
        .collect::<PyResult<Vec<_>>>()?;
    let (json, csv) = py
        .detach(|| {
            let outside: Vec<study::Outside> = compared
                .iter()
                .map(|(name, text, file)| study::Outside {
                    name,
                    source: study::Source { text, name: file },
                })
                .collect();
            study::study(
                study::Source {
                    text: &text,
                    name: &name,
                },
                reference.as_ref().map(|(text, name)| study::Source { text, name }),
                &outside,
                &o,
                calibrate_mag,
                gates,
            )
            .map(|st| (st.json().to_string(), st.csv()))
            .map_err(|e| {
                use simnet::analysis::attitude::AttitudeError::{Length, NameTaken};
                use study::StudyError::{Attitude, OutsideName, OutsideRows, OutsideSpan};
                let key = match e {
                    OutsideName { .. } | OutsideRows { .. } | OutsideSpan { .. } => "compare",
                    Attitude {
                        source: NameTaken { .. } | Length { .. },
                        ..
                    } => "compare",
                    _ => "file",
                };
                (key, e.to_string())
            })
        })
        .map_err(|(key, e)| bad(key, e))?;
    let d = PyDict::new(py);
    d.set_item("json", json)?;
    d.set_item("csv", PyBytes::new(py, csv.as_bytes()))?;
    Ok(d)
}

/// The built-in topologies: (name, description).
#[pyfunction]
fn builtins() -> Vec<(String, String)> {
    builtin::ALL
        .iter()
        .map(|(name, text)| {
            let d = Scenario::from_toml(text, name)
                .map(|t| t.description().to_string())
                .unwrap_or_else(|e| format!("(invalid: {e})"));
            (name.to_string(), d)
        })
        .collect()
}

/// The distributed estimators: (name, reference, what each round sends, parameters).
#[pyfunction]
fn estimators() -> Vec<(&'static str, &'static str, &'static str, &'static str)> {
    simnet::estimators::schemes()
        .into_iter()
        .map(|s| (s.name, s.reference, s.messages, s.parameters))
        .collect()
}

/// simnet's version (and the commit it was built from, when known).
#[pyfunction]
fn version() -> String {
    campaign::simnet_build()
}

#[pymodule]
fn _simnet(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ScenarioError", m.py().get_type::<ScenarioError>())?;
    m.add_class::<PyScenario>()?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(sweep, m)?)?;
    m.add_function(wrap_pyfunction!(bounds, m)?)?;
    m.add_function(wrap_pyfunction!(attitude, m)?)?;
    m.add_function(wrap_pyfunction!(builtins, m)?)?;
    m.add_function(wrap_pyfunction!(estimators, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
