"""simnet from Python: scenarios, runs over real UDP sockets, campaigns and covariance bounds.

Runs are simnet's own (the Rust crate, compiled into this package): the same seed gives the same numbers as the
``simnet`` command line. Tables come back as pandas DataFrames (pyarrow tables when pandas is not installed),
matrices as numpy arrays.

>>> import simnet
>>> r = simnet.run("ring3", loss=0.2, duration=5)
>>> r.nodes[["id", "networked_mean_error", "independent_mean_error"]]   # doctest: +SKIP

Options are those of ``simnet run`` by name (``loss``, ``loss_model``, ``burst``, ``delay``, ``jitter``,
``duplicate``, ``corrupt``, ``duration``, ``rate``, ``seed``, ``estimators``, ``rounds``, ``key_file``, ``auth``);
any other name is a scenario key as in its file, ``.`` written ``__`` (``consensus__gate=0.999``), or given in
``set={"consensus.gate": 0.999}``. Every call releases the GIL; Ctrl-C stops a run or a sweep, keeping what it
did (see :class:`Interrupted`).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from collections import namedtuple
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _simnet
from ._simnet import ScenarioError

__all__ = [
    "Scenario",
    "ScenarioError",
    "Interrupted",
    "Result",
    "Bounds",
    "Estimator",
    "run",
    "sweep",
    "bounds",
    "attitude",
    "Attitude",
    "topologies",
    "estimators",
    "__version__",
]

__version__ = _simnet.version()

Estimator = namedtuple("Estimator", ["name", "reference", "messages", "parameters"])
Estimator.__doc__ = "A distributed estimator simnet runs: its name, its reference, what each round sends, its parameters."

Bounds = namedtuple("Bounds", ["lambda_min", "lambda_bar", "trace_S", "trace_V", "S", "V", "rho", "measured"])
Bounds.__doc__ = """Sinopoli et al. (2004)'s bounds of the expected prediction covariance at one arrival rate λ.

lambda_min: 1 − 1/ρ(A)², below which the expected covariance diverges; lambda_bar: the critical arrival rate (upper
end of its bracket); trace_S, trace_V: traces of the lower and upper bounds S̄ ≤ E[P] ≤ V̄ (inf when no fixed point
exists, nan when the iteration did not settle); S, V: the matrices (None then); rho: ρ(A); measured: the mean
trace P_(k|k−1) of a run at λ (with measure=True, else None)."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C stopped a run or a sweep. ``result`` holds what was done: the partial :class:`Result` of a run (its
    summary says ``interrupted``), or for a sweep the directory whose stored runs a later call with the same
    arguments keeps."""

    def __init__(self, message: str, result: Any = None):
        super().__init__(message)
        self.result = result


def _plain(v: Any) -> Any:
    """numpy scalars and arrays, paths and tuples as the plain values a scenario holds."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, os.PathLike):
        return os.fspath(v)
    if isinstance(v, Mapping):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    return v


class Scenario:
    """A validated scenario (a topology file with options applied). Immutable: ``with_`` returns a new one.

    Build one with :meth:`builtin`, :meth:`from_toml` or :meth:`resolve`; every problem raises
    :class:`ScenarioError` naming the key.
    """

    __slots__ = ("_native",)

    def __init__(self, native: "_simnet.Scenario"):
        self._native = native

    @classmethod
    def builtin(cls, name: str) -> "Scenario":
        """A built-in topology (``simnet.topologies()`` lists them)."""
        return cls(_simnet.Scenario.builtin(name))

    @classmethod
    def resolve(cls, name_or_path: Union[str, os.PathLike]) -> "Scenario":
        """As ``--topology``: a path, then ``./topologies/NAME.toml``, then a built-in."""
        return cls(_simnet.Scenario.resolve(os.fspath(name_or_path)))

    @classmethod
    def from_toml(cls, text_or_path: Union[str, os.PathLike]) -> "Scenario":
        """A scenario from TOML text, or from the file at a path."""
        if isinstance(text_or_path, os.PathLike):
            return cls(_simnet.Scenario.from_path(os.fspath(text_or_path)))
        text = str(text_or_path)
        if "\n" not in text and "=" not in text and Path(text).is_file():
            return cls(_simnet.Scenario.from_path(text))
        return cls(_simnet.Scenario.from_toml(text, "<string>"))

    def with_(self, set: Optional[Mapping[str, Any]] = None, **overrides: Any) -> "Scenario":
        """This scenario with ``simnet run``'s options and scenario keys applied, validated as a whole.

        ``s.with_(loss=0.2, rounds=3, consensus__gate=0.999)`` or ``s.with_(set={"node[0].sensor.gyro_noise": 0.01})``.
        An option set to None is left as the file has it.
        """
        opts: Dict[str, Any] = {k: _plain(v) for k, v in overrides.items()}
        if set:
            opts["set"] = {str(k): _plain(v) for k, v in set.items()}
        return Scenario(self._native.with_options(opts))

    def to_toml(self) -> str:
        """The TOML this scenario would be read from (every change applied)."""
        return self._native.to_toml()

    def warnings(self) -> List[str]:
        """What ``simnet validate`` would warn about."""
        return list(self._native.warnings())

    def positions(self, t: float = 0.0) -> List[Tuple[int, float, float, float]]:
        """Every node's position at time ``t`` (s), in metres, as ``(id, x, y, z)`` in node order: an IMU
        network's nodes ride the package along ``sim.trajectory``; a linear system's stand where the scenario puts
        them (``node[].position_m``; rgg50 where its graph was drawn)."""
        return [tuple(p) for p in self._native.positions(t)]

    name = property(lambda self: self._native.name, doc="The topology's name.")
    description = property(lambda self: self._native.description, doc="Its description.")
    source = property(lambda self: self._native.source, doc="Where it was read from.")
    model = property(lambda self: self._native.model, doc="The estimation model: pose, attitude or linear.")
    nodes = property(lambda self: self._native.nodes, doc="The number of nodes.")
    links = property(lambda self: self._native.links, doc="The number of directed links.")
    steps = property(lambda self: self._native.steps, doc="Steps of a run.")
    duration_s = property(lambda self: self._native.duration_s, doc="Simulated duration, s.")
    rate_hz = property(lambda self: self._native.rate_hz, doc="Step rate, Hz.")
    seed = property(lambda self: self._native.seed, doc="The run seed.")
    estimators = property(lambda self: list(self._native.estimators), doc="Distributed estimators a run holds.")
    digest = property(lambda self: self._native.digest, doc="SHA-256 of the resolved scenario.")

    def __repr__(self) -> str:
        return repr(self._native)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scenario) and other.digest == self.digest

    def __hash__(self) -> int:
        return hash(self.digest)


def _scenario(s: Union[Scenario, str, os.PathLike], overrides: Mapping[str, Any]) -> Scenario:
    sc = s if isinstance(s, Scenario) else Scenario.resolve(s)
    return sc.with_(**overrides) if overrides else sc


def _table(data: Optional[bytes]):
    """A CSV table as a pandas DataFrame (pyarrow table without pandas); None for a table the run did not make."""
    if data is None:
        return None
    try:
        import pandas as pd
    except ImportError:
        try:
            import pyarrow.csv as pacsv
        except ImportError as e:
            raise ImportError("simnet's tables need pandas or pyarrow: pip install pandas") from e
        return pacsv.read_csv(io.BytesIO(data))
    return _typed(pd.read_csv(io.BytesIO(data)))


# Counts and indices: whole numbers even where a row leaves them empty (a fused row has no node).
_INTEGER = {
    "step", "node", "id", "from", "to", "channel", "seed", "point", "sent", "delivered", "late", "corrupted",
    "lost", "lost_random", "lost_down", "duplicated", "longest_loss_run", "steps", "n",
}


def _typed(df):
    """Integer columns with gaps as nullable Int64, true/false columns with gaps as nullable booleans."""
    import pandas as pd

    for c in df.columns:
        col = df[c]
        if c in _INTEGER and pd.api.types.is_float_dtype(col) and (col.dropna() % 1 == 0).all():
            df[c] = col.astype("Int64")
        elif col.dtype == object and col.notna().any() and col.dropna().map(lambda v: isinstance(v, bool)).all():
            df[c] = col.astype("boolean")
    return df


def _frame(records: List[dict]):
    """Records (nested dicts flattened with `_`) as a DataFrame, or a pyarrow table without pandas."""
    try:
        import pandas as pd
    except ImportError:
        import pyarrow as pa

        return pa.Table.from_pylist([_flatten(r) for r in records])
    return pd.DataFrame([_flatten(r) for r in records])


def _flatten(d: Mapping[str, Any], prefix: str = "") -> Dict[str, Any]:
    out: Dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(_flatten(v, f"{prefix}{k}_"))
        else:
            out[f"{prefix}{k}"] = v
    return out


class Result:
    """One run: ``summary`` (the ``summary.json`` schema, as a dict) and its tables as DataFrames, each read
    when first asked for.

    - ``nodes``: one row per node, the summary's figures flattened (``networked_mean_error``, ``rejected_replay``);
    - ``links``: ``links.csv``, one row per directed link;
    - ``trace``: ``trace.csv``, per step, node and filter (networked, independent, and the fused rows);
    - ``measurements``: every sensing node's own measurements per step;
    - ``estimators``: every distributed estimator's estimate per node and step (None when the run held none).

    ``trace``, ``measurements`` and ``estimators`` are None for a run made with ``tables=False``.
    """

    def __init__(self, raw: Mapping[str, Any], scenario: Scenario):
        self.scenario = scenario
        self.summary: Dict[str, Any] = json.loads(raw["summary"])
        self._raw = {k: raw[k] for k in ("trace", "links", "measurements", "estimators")}
        self._tables: Dict[str, Any] = {}

    def _get(self, name: str):
        if name not in self._tables:
            self._tables[name] = _table(self._raw[name])
        return self._tables[name]

    @property
    def nodes(self):
        return _frame(self.summary["nodes"])

    links = property(lambda self: self._get("links"), doc="links.csv: one row per directed link.")
    trace = property(lambda self: self._get("trace"), doc="trace.csv: per step, node and filter.")
    measurements = property(lambda self: self._get("measurements"), doc="measurements.csv: each node's own.")
    estimators = property(lambda self: self._get("estimators"), doc="estimators.csv (None without estimators).")

    @property
    def interrupted(self) -> bool:
        """Whether Ctrl-C cut the run short."""
        return bool(self.summary.get("interrupted"))

    def csv(self, name: str) -> bytes:
        """A table as the CSV bytes ``simnet run --out`` writes (``trace``, ``links``, ``measurements``,
        ``estimators``)."""
        if name in self._raw and self._raw[name] is None:
            raise KeyError(f"table {name!r} was not made (a run with tables=False, or without estimators)")
        if name not in self._raw:
            raise KeyError(f"no table {name!r} (known: {', '.join(self._raw)})")
        return self._raw[name]

    def __repr__(self) -> str:
        s = self.summary
        return (
            f"<simnet.Result {s['topology']} seed {s['seed']}: {s['steps']} steps, {len(s['nodes'])} nodes"
            f"{', interrupted' if s.get('interrupted') else ''}>"
        )


def _option_error(key: str, message: str) -> ScenarioError:
    """A bad argument, raised as the native layer raises one: ``key`` names it."""
    e = ScenarioError(message)
    e.message, e.key, e.problems = message, key, [(key, message)]
    return e


def _progress(progress: Union[bool, Callable[[int, int], Any], None], unit: str):
    """A callback (done, total) that draws a tqdm bar when progress is True and tqdm is installed."""
    if progress is None or progress is False:
        return None, lambda: None
    if callable(progress):
        return progress, lambda: None
    if progress is not True:
        raise _option_error(
            "progress", f"progress: expected True, False or a callable (done, total), got {type(progress).__name__}"
        )
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None, lambda: None
    bar = {}

    def cb(done: int, total: int) -> None:
        if "b" not in bar:
            bar["b"] = tqdm(total=total, unit=unit)
        bar["b"].n = done
        bar["b"].refresh()

    return cb, lambda: bar["b"].close() if "b" in bar else None


def run(
    scenario: Union[Scenario, str, os.PathLike],
    progress: Union[bool, Callable[[int, int], Any], None] = False,
    tables: bool = True,
    **overrides: Any,
) -> Result:
    """Run a scenario (or a topology name or path) over UDP sockets on loopback, on simnet's virtual clock, as
    ``simnet run`` does: the same seed gives the same summary.

    ``overrides`` are ``simnet run``'s options and scenario keys (see :meth:`Scenario.with_`). ``progress``: True
    draws a tqdm bar (when tqdm is installed), or a callable gets ``(steps_done, steps)``. Ctrl-C stops the run
    and raises :class:`Interrupted` holding the partial result. ``tables=False`` makes no per-step rows (``trace``,
    ``measurements`` and ``estimators`` are then None; ``summary``, ``nodes`` and ``links`` are whole): a run then
    costs what ``simnet --json`` does.
    """
    sc = _scenario(scenario, overrides)
    cb, close = _progress(progress, "step")
    try:
        raw = _simnet.run(sc._native, cb, tables)
    finally:
        close()
    result = Result(raw, sc)
    if raw["keyboard_interrupt"]:
        raise Interrupted(f"run of {sc.name} stopped at step {result.summary['steps']}", result)
    return result


def _axis(key: str, values: Any) -> str:
    if isinstance(values, str):
        return f"{key}={values}"
    return f"{key}=" + ",".join(_toml_value(_plain(v)) for v in values)


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    raise TypeError(f"a swept value must be a bool, number or string, got {type(v).__name__}")


def sweep(
    scenario: Union[Scenario, str, os.PathLike],
    set: Union[Mapping[str, Any], Sequence[str]],
    seeds: int = 10,
    estimators: Union[str, Sequence[str], None] = None,
    rounds: Optional[int] = None,
    duration: Optional[float] = None,
    out: Union[str, os.PathLike, None] = None,
    transport: str = "memory",
    progress: Union[bool, Callable[[int, int], Any], None] = False,
) -> Tuple[Any, Any]:
    """A campaign, as ``simnet sweep``: every point of the swept keys × seeds 1 … ``seeds``, on every core.

    ``set``: ``{"link.loss.p": [0, 0.1, 0.2]}`` (values, or a ``"START:END:STEP"`` string) or the command line's
    ``["link.loss.p=0:0.3:0.1"]``; several keys make their product. ``out``: the campaign's directory (default:
    a new temporary one); a campaign stopped half-way runs only what is missing when called again.
    Returns ``(runs, points)``: ``runs.csv`` (one row per run) and ``points.csv`` (per point and estimator: mean,
    sd, n and the 95 % interval of each figure). Their ``attrs["dir"]`` is the directory.
    """
    if isinstance(scenario, Scenario):
        sc = scenario
    else:
        sc = Scenario.resolve(scenario)
    axes = [_axis(k, v) for k, v in set.items()] if isinstance(set, Mapping) else [str(s) for s in set]
    est = None if estimators is None else (estimators if isinstance(estimators, str) else list(estimators))
    cb, close = _progress(progress, "run")
    made = out is None
    directory = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="simnet-sweep-"))
    try:
        raw = _simnet.sweep(sc._native, axes, directory, seeds, est, rounds, duration, transport, cb)
    except ScenarioError:
        # Refused before any run: the temporary directory this call made holds nothing.
        if made:
            shutil.rmtree(directory, ignore_errors=True)
        raise
    finally:
        close()
    if raw["keyboard_interrupt"] or raw["stopped"]:
        raise Interrupted(
            f"sweep stopped: {raw['ran']} runs made now, {raw['kept']} kept, {raw['stopped']} not started; "
            f"call again with out={str(directory)!r} to run only what is missing",
            str(directory),
        )
    if raw["failed"]:
        key, point, seed, why = raw["failed"][0]
        raise RuntimeError(
            f"{len(raw['failed'])} runs failed; first: run {key} ({point}, seed {seed}): {why} "
            f"(the runs made are kept in {str(directory)!r}: call again with out= to run only what is missing)"
        )
    runs = _table((directory / "runs.csv").read_bytes())
    points = _table((directory / "points.csv").read_bytes())
    for t in (runs, points):
        if hasattr(t, "attrs"):
            t.attrs["dir"] = str(directory)
    return runs, points


def _matrix(name: str, m: Any) -> List[List[float]]:
    try:
        a = np.atleast_2d(np.asarray(m, dtype=float))
    except (TypeError, ValueError) as e:
        raise _option_error(name, f"{name}: expected a matrix of numbers ({e})") from None
    if a.ndim != 2:
        raise _option_error(name, f"{name}: expected a matrix, got an array of {a.ndim} dimensions")
    return a.tolist()


def bounds(
    A: Any = None,
    C: Any = None,
    Q: Any = None,
    R: Any = None,
    lam: Union[float, Iterable[float]] = 0.5,
    scenario: Union[Scenario, str, None] = None,
    measure: bool = False,
):
    """Sinopoli et al. (2004)'s covariance bounds of a Kalman filter whose measurements arrive with probability λ.

    Give ``A, C, Q, R`` (numpy arrays or scalars), or ``scenario`` (a linear-model scenario, e.g.
    ``"sinopoli-scalar"``); ``measure=True`` also runs the scenario at each λ and reports the measured mean trace
    P_(k|k−1). One λ gives a :class:`Bounds`; several give a DataFrame with columns lambda, trace_S, trace_V,
    measured (``attrs`` hold lambda_min, lambda_bar, rho).
    """
    if isinstance(A, (Scenario, str)) and scenario is None:
        A, scenario = None, A
    native = None
    if scenario is not None:
        native = (scenario if isinstance(scenario, Scenario) else Scenario.resolve(scenario))._native
    mats = [None if m is None else _matrix(n, m) for n, m in zip("ACQR", (A, C, Q, R))]
    single = np.ndim(lam) == 0
    lams = [float(lam)] if single else [float(x) for x in lam]
    raw = _simnet.bounds(lams, *mats, native, measure)

    def arr(m):
        return None if m is None else np.array(m)

    if single:
        l, ts, tv, sm, vm, measured = raw["rows"][0]
        return Bounds(raw["lambda_min"], raw["lambda_bar"], ts, tv, arr(sm), arr(vm), raw["rho"], measured)
    records = [
        {"lambda": l, "trace_S": ts, "trace_V": tv, "measured": m} for (l, ts, tv, _, _, m) in raw["rows"]
    ]
    try:
        import pandas as pd
    except ImportError:
        import pyarrow as pa

        return pa.Table.from_pylist(records)
    df = pd.DataFrame(records, columns=["lambda", "trace_S", "trace_V", "measured"]).astype(float)
    df.attrs.update(lambda_min=raw["lambda_min"], lambda_bar=raw["lambda_bar"], rho=raw["rho"])
    return df


Attitude = namedtuple("Attitude", ["summary", "samples"])
Attitude.__doc__ = """A recording studied by :func:`attitude`: ``summary`` is what ``simnet attitude --json`` prints (what
was read and estimated, the gates, each filter's scores); ``samples`` is ``attitude.csv`` as a DataFrame (time, the
reference, the gates' verdicts, each filter's quaternion and error in degrees)."""


def attitude(
    file: Union[str, os.PathLike],
    reference: Union[str, os.PathLike, None] = None,
    *,
    columns: Optional[str] = None,
    units: Optional[str] = None,
    rate: Optional[float] = None,
    gates: Optional[str] = None,
    calibrate_mag: bool = False,
    compare: Optional[Dict[str, Union[str, os.PathLike]]] = None,
) -> Attitude:
    """The EKFs, Madgwick, Mahony, VQF and the gyro alone on a recording, scored against its reference orientation, as
    ``simnet attitude FILE [--reference REFERENCE]`` does; the options take the command line's values
    (``columns="t=Counter/rate,ax=Acc_X"``, ``units="gyro=deg/s"``, ``gates="off"``). ``compare`` maps a name to
    the file of a filter run elsewhere (``--compare NAME=FILE``), scored beside simnet's. Bad input raises
    :class:`ScenarioError` naming the option (``key``) with the command line's message."""
    raw = _simnet.attitude(
        os.fspath(file),
        None if reference is None else os.fspath(reference),
        columns,
        units,
        rate,
        gates,
        calibrate_mag,
        [(name, os.fspath(path)) for name, path in (compare or {}).items()],
    )
    return Attitude(json.loads(raw["json"]), _table(raw["csv"]))


def topologies() -> Dict[str, str]:
    """The built-in topologies: name → description (``simnet topologies``)."""
    return dict(_simnet.builtins())


def estimators() -> List[Estimator]:
    """The distributed estimators simnet runs, with their references (``simnet estimators``)."""
    return [Estimator(*e) for e in _simnet.estimators()]
