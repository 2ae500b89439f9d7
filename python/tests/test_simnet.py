"""The Python package against the command line it mirrors, and against independent computations."""

import json
import math
import os
import signal
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import simnet

# What depends on the machine and its load, not on the run (`summary::LOAD_DEPENDENT`).
LOAD_DEPENDENT = {"transport"}


def same_summary(a, b):
    strip = lambda s: {k: v for k, v in s.items() if k not in LOAD_DEPENDENT}
    assert strip(a) == strip(b)


# ---- listing -------------------------------------------------------------------------------------------------


def test_topologies_are_the_command_lines(cli):
    listed = [line.split()[0] for line in cli("topologies").stdout.splitlines() if line.strip()]
    tops = simnet.topologies()
    assert list(tops) == listed
    assert "ring3" in tops and tops["ring3"]


def test_estimators_carry_their_references(cli):
    names = [e.name for e in simnet.estimators()]
    out = cli("estimators").stdout
    assert names and all(n in out for n in names)
    assert all(e.reference in out for e in simnet.estimators())
    assert {"independent", "centralized", "kcf", "icf", "sequeira"} <= set(names)


# ---- runs: the same numbers as the CLI ----------------------------------------------------------------------

CASES = [
    ("ring3", {"loss": 0.2, "duration": 5}, ["--loss", "0.2", "--duration", "5"]),
    (
        "ring3",
        {"loss": 0.3, "loss_model": "gilbert-elliott", "burst": 3, "duration": 4, "seed": 7,
         "estimators": ["kcf", "centralized"], "rounds": 2, "consensus__gate": 0.999},
        ["--loss", "0.3", "--loss-model", "gilbert-elliott", "--burst", "3", "--duration", "4", "--seed", "7",
         "--estimators", "kcf,centralized", "--rounds", "2", "--set", "consensus.gate=0.999"],
    ),
    ("sinopoli-scalar", {"loss": 0.5, "duration": 20}, ["--loss", "0.5", "--duration", "20"]),
    ("ring3-attacked", {"duration": 25}, ["--duration", "25"]),
    ("ring3-radio", {"duration": 3}, ["--duration", "3"]),
]


@pytest.mark.parametrize("topology,opts,args", CASES, ids=[c[0] + str(i) for i, c in enumerate(CASES)])
def test_a_run_gives_the_summary_simnet_json_gives(cli, topology, opts, args):
    py = simnet.run(topology, **opts).summary
    js = json.loads(cli("-q", "-t", topology, *args, "--json").stdout)
    same_summary(py, js)


def test_tables_are_the_files_simnet_run_writes(cli, tmp_path):
    r = simnet.run("ring3", loss=0.2, duration=3, estimators="kcf,centralized")
    cli("-q", "-t", "ring3", "--loss", "0.2", "--duration", "3", "--estimators", "kcf,centralized",
        "--out", str(tmp_path))
    for name in ("trace", "links", "measurements", "estimators"):
        assert r.csv(name) == (tmp_path / f"{name}.csv").read_bytes(), name
    same_summary(r.summary, json.loads((tmp_path / "summary.json").read_text()))


def test_tables_are_typed_frames():
    r = simnet.run("ring3", loss=0.2, duration=3, estimators="kcf")
    t = r.trace
    assert isinstance(t, pd.DataFrame)
    assert list(t.columns[:4]) == ["step", "t", "node", "estimator"]
    assert t["step"].dtype == np.int64 and t["node"].dtype == "Int64"
    assert t["error"].dtype == np.float64 and t["feasible"].dtype == "boolean"
    assert set(t["estimator"]) == {"networked", "independent", "kcf", "fused", "fused_median"}
    # Every step of every node: networked, independent and each estimator run.
    steps = r.summary["steps"]
    for name in ["networked", "independent", "kcf"]:
        assert (t["estimator"] == name).sum() == 3 * steps, name
    links = r.links
    assert len(links) == 6 and links["sent"].dtype == np.int64
    np.testing.assert_allclose(links["loss_rate"], 1 - links["delivered"] / links["sent"], atol=1e-12)
    n = r.nodes
    assert list(n["id"]) == [0, 1, 2]
    assert {"networked_mean_error", "independent_mean_error", "error_ratio", "rejected_replay"} <= set(n.columns)
    np.testing.assert_allclose(n["error_ratio"], n["networked_mean_error"] / n["independent_mean_error"])
    assert set(r.estimators["estimator"]) == {"kcf"} and r.estimators["node"].dtype == np.int64
    m = r.measurements
    assert list(m.columns) == ["step", "t", "node", "channel", "rows", "values", "r"]


def test_a_run_without_tables_has_the_same_summary():
    full = simnet.run("ring3", loss=0.2, duration=3, estimators="kcf")
    bare = simnet.run("ring3", loss=0.2, duration=3, estimators="kcf", tables=False)
    same_summary(bare.summary, full.summary)
    assert bare.trace is None and bare.measurements is None and bare.estimators is None
    pd.testing.assert_frame_equal(bare.links, full.links)
    with pytest.raises(KeyError):
        bare.csv("trace")


def test_a_run_without_estimators_has_no_estimator_table():
    r = simnet.run("sinopoli-scalar", duration=2)
    assert r.scenario.estimators == [] and r.estimators is None


# ---- scenarios and overrides --------------------------------------------------------------------------------


def test_overrides_change_the_scenario_as_the_cli_does():
    base = simnet.Scenario.builtin("ring3")
    s = base.with_(duration=3, rate=50, seed=9, loss=0.1, set={"consensus.self": 0.6})
    assert (s.duration_s, s.rate_hz, s.seed, s.steps) == (3, 50, 9, 150)
    assert 'self = 0.6' in s.to_toml()
    assert s != base and s == base.with_(duration=3, rate=50, seed=9, loss=0.1, consensus__self=0.6)
    # The TOML read back is the same scenario.
    assert simnet.Scenario.from_toml(s.to_toml()).digest == s.digest
    # numpy values are plain values.
    assert base.with_(loss=np.float64(0.1), seed=np.int64(9)).seed == 9


def test_from_toml_takes_text_or_a_path(tmp_path):
    text = simnet.Scenario.builtin("line4").to_toml()
    f = tmp_path / "line4.toml"
    f.write_text(text)
    assert simnet.Scenario.from_toml(f).digest == simnet.Scenario.from_toml(text).digest
    assert simnet.Scenario.from_toml(str(f)).nodes == 4


# ---- errors carry the CLI's key and message ------------------------------------------------------------------


def cli_error(cli, *args):
    p = cli("-q", *args, check=False)
    assert p.returncode == 2, p.stderr
    return p.stderr.strip().removeprefix("error: ")


def test_an_unknown_key_names_it(cli):
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("ring3", set={"consensus.nope": 1})
    assert e.value.key == "consensus.nope"
    assert str(e.value) == cli_error(cli, "-t", "ring3", "--set", "consensus.nope=1")


def test_a_value_out_of_range_names_its_key(cli):
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.Scenario.builtin("ring3").with_(link__loss__p=1.5)
    assert e.value.key == "link.loss.p"
    assert str(e.value) == cli_error(cli, "-t", "ring3", "--set", "link.loss.p=1.5")
    # An option's value out of its range: the option named, in the command line's words.
    for kwargs, argv, says in [
        (dict(delay=-1), ["--delay", "-1"], "must be a non-negative number, got -1"),
        (dict(loss=1.5), ["--loss", "1.5"], "must be a probability in [0, 1], got 1.5"),
        (dict(rounds=101), ["--rounds", "101"], "must be 1 to 100, got 101"),
        (dict(loss=0.2, loss_model="gilbert-elliott", burst=0.5), ["--loss", "0.2", "--loss-model",
                                                                  "gilbert-elliott", "--burst", "0.5"],
         "a mean loss run is at least 1 packet, got 0.5"),
    ]:
        with pytest.raises(simnet.ScenarioError) as e:
            simnet.run("ring3", **kwargs)
        name = argv[-2].removeprefix("--").replace("-", "_")
        assert e.value.key == name and e.value.problems[0][0] == name, (kwargs, e.value.key)
        assert says in str(e.value) and says in cli_error(cli, "-t", "ring3", *argv), (kwargs, str(e.value))


def test_options_that_do_not_go_together_name_the_option(cli):
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("ring3", burst=3)
    assert e.value.key == "burst"
    assert str(e.value) == cli_error(cli, "-t", "ring3", "--burst", "3")
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("ring3", loss=0.2, loss_model="gilbert-elliott")
    assert e.value.key == "loss_model"
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("ring3", rounds=0)
    assert e.value.key == "rounds"
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("ring3", estimators="kcf,nope")
    assert e.value.key == "estimators" and "unknown estimator `nope`" in str(e.value)


def test_an_unknown_topology_says_where_it_looked(cli):
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.run("no-such-topology")
    assert str(e.value) == cli_error(cli, "-t", "no-such-topology")
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.Scenario.builtin("no-such-topology")
    assert e.value.key == "topology" and "ring3" in str(e.value)


def test_a_malformed_file_is_an_error_not_a_crash():
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.Scenario.from_toml("name = 'x'\n[sim\n")
    assert "<string>" in str(e.value)
    with pytest.raises(TypeError):
        simnet.Scenario.builtin("ring3").with_(consensus__self=object())
    with pytest.raises(simnet.ScenarioError):
        simnet.run("ring3", loss="lots")


# ---- campaigns ---------------------------------------------------------------------------------------------


def test_a_sweep_writes_what_simnet_sweep_writes(cli, tmp_path):
    runs, points = simnet.sweep("ring3", {"link.loss.p": [0, 0.2]}, seeds=3, duration=2,
                                estimators="kcf,centralized", out=tmp_path / "py")
    cli("sweep", "-q", "-t", "ring3", "--set", "link.loss.p=0,0.2", "--seeds", "3", "--duration", "2",
        "--estimators", "kcf,centralized", "--out", str(tmp_path / "cli"))
    for name in ("runs.csv", "points.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    assert len(runs) == 6 and set(runs["seed"]) == {1, 2, 3}
    assert {"point", "estimator", "metric", "n", "mean", "sd", "ci95_low", "ci95_high"} <= set(points.columns)
    assert runs.attrs["dir"] == str(tmp_path / "py")
    # Where a figure was measured, the confidence interval holds the mean; where not (n = 0), all are empty.
    m = points[points["n"] >= 2]
    assert len(m) > 0 and ((m["ci95_low"] <= m["mean"] + 1e-12) & (m["mean"] <= m["ci95_high"] + 1e-12)).all()
    assert points[points["n"] == 0]["mean"].isna().all()


def test_a_sweep_takes_the_command_lines_ranges_and_resumes(tmp_path):
    out = tmp_path / "s"
    runs, _ = simnet.sweep("ring3", ["link.loss.p=0:0.2:0.1"], seeds=2, duration=1, out=out)
    assert sorted(runs["link.loss.p"].unique()) == pytest.approx([0, 0.1, 0.2])
    before = {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()}
    again, _ = simnet.sweep("ring3", ["link.loss.p=0:0.2:0.1"], seeds=2, duration=1, out=out)
    assert {p.name: p.stat().st_mtime_ns for p in (out / "runs").iterdir()} == before
    pd.testing.assert_frame_equal(runs, again)


def test_a_bad_sweep_names_what_is_wrong(tmp_path):
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.sweep("ring3", {"consensus.nope": [1, 2]}, seeds=1, out=tmp_path / "a")
    assert e.value.key and "nope" in e.value.key
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.sweep("ring3", {"link.loss.p": [0]}, seeds=0, out=tmp_path / "b")
    assert e.value.key == "seeds"
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.sweep("ring3", {"link.loss.p": [0]}, transport="carrier-pigeon", out=tmp_path / "c")
    assert e.value.key == "transport"


# ---- the GIL ----------------------------------------------------------------------------------------------


def test_a_run_releases_the_gil():
    # With a switch interval of 100 s the interpreter never takes the GIL from a thread that holds it: the main thread
    # can make its call during the run only if the run lets go of the GIL while it works.
    import sys
    import threading

    entered, returned, during = threading.Event(), threading.Event(), []

    def work():
        entered.set()
        simnet.run("ring3", duration=30)
        returned.set()

    old = sys.getswitchinterval()
    sys.setswitchinterval(100)
    try:
        t = threading.Thread(target=work)
        t.start()
        entered.wait()
        b = simnet.bounds(-1.25, 1, 1, 2.5, lam=0.5)
        during.append(not returned.is_set())
        t.join()
    finally:
        sys.setswitchinterval(old)
    assert round(b.trace_S, 4) == 4.5714
    assert during == [True], "the main thread could not run while simnet.run was running"


# ---- Ctrl-C ------------------------------------------------------------------------------------------------


def test_ctrl_c_stops_a_run_and_keeps_what_it_did():
    # The signal is sent once the run has made steps: the test waits for that event, not for a time.
    def on_progress(done, total):
        if done > 0:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(simnet.Interrupted) as e:
        simnet.run("ring3", duration=3600, progress=on_progress)
    r = e.value.result
    assert isinstance(e.value, KeyboardInterrupt)
    assert r.interrupted and 0 < r.summary["steps"] < 360_000
    assert (r.trace["estimator"] == "networked").sum() == 3 * r.summary["steps"]


def test_ctrl_c_stops_a_sweep_and_a_second_call_finishes_it(tmp_path):
    out = tmp_path / "s"

    def on_progress(done, total):
        if done >= 2:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(simnet.Interrupted) as e:
        simnet.sweep("ring3", {"link.loss.p": [0, 0.1, 0.2, 0.3]}, seeds=100, duration=3, out=out,
                     progress=on_progress)
    kept = len(list((out / "runs").iterdir()))
    assert e.value.result == str(out) and 2 <= kept < 400
    runs, _ = simnet.sweep("ring3", {"link.loss.p": [0, 0.1, 0.2, 0.3]}, seeds=100, duration=3, out=out)
    assert len(runs) == 400


def test_a_progress_callback_that_raises_stops_the_run():
    class Boom(Exception):
        pass

    def on_progress(done, total):
        assert total == 360_000
        if done > 0:
            raise Boom()

    with pytest.raises(Boom):
        simnet.run("ring3", duration=3600, progress=on_progress)


def test_a_callback_raising_at_the_end_of_a_short_run_is_raised():
    # The run ends before the first poll: only the final report calls the callback.
    def on_progress(done, total):
        raise ZeroDivisionError("from the callback")

    with pytest.raises(ZeroDivisionError, match="from the callback"):
        simnet.run("ring3", duration=0.02, progress=on_progress)


@pytest.mark.parametrize("progress", [5, "yes", [1]])
def test_a_progress_that_is_neither_a_bool_nor_a_callable_is_refused(progress):
    with pytest.raises(simnet.ScenarioError, match="progress: expected True, False or a callable") as e:
        simnet.run("ring3", duration=0.02, progress=progress)
    assert e.value.key == "progress"


def test_a_refused_sweep_leaves_no_temporary_directory(tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.sweep("ring3", {"link.loss.p": [0, 2]}, seeds=1, duration=0.1)
    assert e.value.key == "link.loss.p"
    assert list(tmp_path.iterdir()) == []


def test_positions_come_from_the_world():
    rgg = simnet.Scenario.builtin("rgg50").positions()
    assert len(rgg) == 50 and [p[0] for p in rgg] == list(range(50))
    assert all(0 <= x <= 100 and 0 <= y <= 100 and z == 0 for _, x, y, z in rgg)
    # The rgg50 file lists node 1 at (87.89…, 67.78…): the positions its graph was drawn from.
    assert math.isclose(rgg[1][1], 87.89333408223794) and math.isclose(rgg[1][2], 67.78068805708205)
    # ring3's nodes ride the package along the spiral: together at its origin, moving with it.
    ring = simnet.Scenario.builtin("ring3")
    start, later = ring.positions(), ring.positions(t=2.5)
    assert len({p[1:] for p in start}) == 1
    assert math.dist(start[0][1:], later[0][1:]) > 1.0


def test_a_ragged_matrix_is_a_scenario_error_naming_it():
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.bounds([[1, 2], [3]], 1, 1, 1)
    assert e.value.key == "A"


# ---- bounds ------------------------------------------------------------------------------------------------

A, C, Q, R = -1.25, 1.0, 1.0, 2.5


def independent_bounds(lam):
    """Sinopoli et al. (2004) for a scalar system: S̄ = (1−λ)A²S̄ + Q (Thm. 5's lower bound) and the fixed point of
    the MARE V = A²V + Q − λA²V²/(V + R) (the upper bound), solved by hand."""
    a2 = A * A
    s = Q / (1 - (1 - lam) * a2)
    # (V + R)(V − A²V − Q) + λA²V² = 0 → (1 − A² + λA²)V² + (R − A²R − Q)V − QR = 0
    qa, qb, qc = 1 - a2 + lam * a2, R - a2 * R - Q, -Q * R
    v = (-qb + math.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    return s, v


def test_bounds_match_the_rust_crate_and_the_closed_form():
    b = simnet.bounds(np.array([[A]]), np.array([[C]]), np.array([[Q]]), np.array([[R]]), lam=0.5)
    assert b.lambda_min == pytest.approx(0.36) and b.lambda_bar == pytest.approx(0.36, abs=1e-6)
    assert b.rho == pytest.approx(1.25)
    assert round(b.trace_S, 4) == 4.5714 and round(b.trace_V, 4) == 11.9559
    assert isinstance(b.S, np.ndarray) and b.S.shape == (1, 1)
    df = simnet.bounds(A, C, Q, R, lam=[0.5, 0.8, 0.9])
    assert list(df.columns) == ["lambda", "trace_S", "trace_V", "measured"]
    assert df["trace_S"].round(4).tolist()[:2] == [4.5714, 1.4545]
    assert df["trace_V"].round(4).tolist()[:2] == [11.9559, 4.3382]
    for lam, s, v in zip(df["lambda"], df["trace_S"], df["trace_V"]):
        es, ev = independent_bounds(lam)
        assert s == pytest.approx(es, rel=1e-6) and v == pytest.approx(ev, rel=1e-6)
    assert df.attrs["lambda_min"] == pytest.approx(0.36)


def test_below_the_critical_rate_there_is_no_upper_bound():
    b = simnet.bounds(A, C, Q, R, lam=0.3)
    assert math.isinf(b.trace_V) and b.V is None


def test_a_measured_run_lies_between_the_bounds():
    b = simnet.bounds("sinopoli-scalar", lam=0.8, measure=True)
    assert b.trace_S <= b.measured <= b.trace_V
    with pytest.raises(ValueError):
        simnet.bounds("ring3", lam=0.5)
    with pytest.raises(simnet.ScenarioError):
        simnet.bounds(A, C, Q, R, lam=1.5)
    with pytest.raises(TypeError):
        simnet.bounds(lam=0.5)


RECORDINGS = Path(__file__).resolve().parents[2] / "tests" / "data" / "recordings"


def test_attitude_is_what_simnet_attitude_prints(cli, tmp_path):
    sensors, quats = RECORDINGS / "ngimu-sensors.csv", RECORDINGS / "ngimu-quaternion.csv"
    a = simnet.attitude(sensors, quats, gates="off")
    p = cli("attitude", str(sensors), "--reference", str(quats), "--gates", "off", "--json", "--out", str(tmp_path))
    assert a.summary == json.loads(p.stdout)
    expected = pd.read_csv(tmp_path / "attitude.csv")
    pd.testing.assert_frame_equal(a.samples, expected)
    # The per-sample errors average to the scores.
    ekf = next(s for s in a.summary["scores"] if s["filter"] == "ekf")
    assert math.isclose(a.samples["ekf_error_deg"].mean(), ekf["as_recorded"]["mean"], rel_tol=1e-9)


def read_xsens():
    """The Xsens recording as numpy arrays: accelerometer, gyro, magnetometer, reference quaternion."""
    lines = [l for l in (RECORDINGS / "xsens-mti.txt").read_text().splitlines() if not l.startswith("//")]
    names = lines[0].split()
    d = np.array([[float(x) for x in l.split()] for l in lines[1:]])
    cols = lambda *c: np.ascontiguousarray(d[:, [names.index(x) for x in c]])
    xyz = lambda s: cols(*(f"{s}_{a}" for a in "XYZ"))
    return xyz("Acc"), xyz("Gyr"), xyz("Mag"), cols("Quat_w", "Quat_x", "Quat_y", "Quat_z")


def qmul(a, b):
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        -1,
    )


def test_attitude_vqf_is_the_published_filter():
    """simnet's `vqf` row (the `vqf-rs` port) against VQF's reference implementation (the `vqf` package, C++) fed
    the same samples at the same sample time: the same attitudes, turned from VQF's east-north-up frame into
    simnet's north-west-up one (−90° about z)."""
    vqf = pytest.importorskip("vqf", reason="pip install vqf to check simnet's VQF against the reference")
    acc, gyr, mag, _ = read_xsens()
    a = simnet.attitude(RECORDINGS / "xsens-mti.txt")
    q = vqf.VQF(1.0 / a.summary["rate_hz"]).updateBatch(gyr, acc, mag)["quat9D"]
    rz = np.tile([math.cos(-math.pi / 4), 0, 0, math.sin(-math.pi / 4)], (len(q), 1))
    want = qmul(rz, q)
    got = a.samples[["vqf_qw", "vqf_qx", "vqf_qy", "vqf_qz"]].to_numpy()
    assert np.abs(np.abs((got * want).sum(-1)) - 1).max() < 1e-12


def test_attitude_scores_a_filter_run_elsewhere(tmp_path):
    """VQF (Laidig & Seel 2023, the `vqf` package) run in Python on the Xsens recording and handed to simnet with
    `compare`: simnet's scores equal numpy's, computed here from the quaternions alone."""
    vqf = pytest.importorskip("vqf", reason="pip install vqf to compare with VQF")
    acc, gyr, mag, ref = read_xsens()
    q = vqf.VQF(0.02).updateBatch(gyr, acc, mag)["quat9D"]
    path = tmp_path / "vqf.csv"
    np.savetxt(path, q, delimiter=",", header="qw,qx,qy,qz", comments="")
    a = simnet.attitude(RECORDINGS / "xsens-mti.txt", compare={"pyvqf": path})
    assert not a.summary["reference_z_down"]
    s = next(s for s in a.summary["scores"] if s["filter"] == "pyvqf")
    assert s["outside"] and s["gated"] is None
    unit = lambda x: x / np.linalg.norm(x, axis=1, keepdims=True)
    q, ref = unit(q), unit(ref)
    angle = lambda u, v: np.degrees(2 * np.arccos(np.clip(np.abs((u * v).sum(-1)), 0, 1)))
    e = angle(q, ref)
    assert math.isclose(e.mean(), s["as_recorded"]["mean"], rel_tol=1e-7)
    assert math.isclose(e.max(), s["as_recorded"]["max"], rel_tol=1e-7)
    # The heading offset: the circular mean of the rotations about z that take the reference to the estimate.
    d = qmul(q, ref * np.array([1, -1, -1, -1]))
    twist = 2 * np.arctan2(d[:, 3], d[:, 0])
    off = np.arctan2(np.sin(twist).mean(), np.cos(twist).mean())
    assert math.isclose(np.degrees(off), s["heading_offset_deg"], rel_tol=1e-7)
    rz = np.tile([np.cos(off / 2), 0, 0, np.sin(off / 2)], (len(ref), 1))
    assert math.isclose(angle(q, qmul(rz, ref)).mean(), s["offset_removed"]["mean"], rel_tol=1e-7)
    assert math.isclose(a.samples["pyvqf_error_deg"].mean(), s["as_recorded"]["mean"], rel_tol=1e-9)


def test_attitude_bad_input_names_the_option(cli):
    xsens = RECORDINGS / "xsens-mti.txt"
    for kwargs, key, says in [
        (dict(compare={"vqf": xsens}), "compare", "is taken"),
        (dict(compare={"a/b": xsens}), "compare", "letters, digits"),
        (dict(units="gyro=furlong/s"), "units", "not a unit of gyro"),
        (dict(gates="heading=1"), "gates", "not a gate"),
        (dict(rate=-1.0), "rate", "positive"),
        (dict(columns="ax=Nope"), "file", "no column `Nope`"),
    ]:
        with pytest.raises(simnet.ScenarioError) as e:
            simnet.attitude(xsens, **kwargs)
        assert e.value.key == key and says in str(e.value), (kwargs, str(e.value))
    with pytest.raises(simnet.ScenarioError) as e:
        simnet.attitude(RECORDINGS / "nope.txt")
    assert "cannot read" in str(e.value)
