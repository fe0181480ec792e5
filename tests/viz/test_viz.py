"""rerun recordings: read back with rerun's own reader and compared with independent constructions.

Every recording here is read with ``rerun.chunk.RrdReader`` (not with the
code that wrote it). Attitudes are rebuilt by composing the logged transforms
along the entity path and compared with matrices built from Table 1's
direction names (conftest.attitude). rerun keeps analytics files under the
home directory, so HOME and XDG_* point into a temporary directory for the
whole module.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import (
    DWELL_S,
    FLIP_S,
    N_POS,
    SPEC_NAMES,
    attitude,
    normal_gravity,
    rest_window,
    table1_positions,
)
from realdata import REPO
from recordings import bars, batch_with, matrices, read_back, scalars, tensor, text_of, times_of

from calib.fit.replay import review_run
from calib.nav.site import Site

RATE_HZ = 40.0  # a short, fast run: 67680 samples for the 28-min sequence
N_SAMPLES = int(round((N_POS * DWELL_S + (N_POS - 1) * FLIP_S) * RATE_HZ))
GIMBAL_PATH = [
    "world/base",
    "world/base/gimbal",
    "world/base/gimbal/outer",
    "world/base/gimbal/outer/middle",
    "world/base/gimbal/outer/middle/inner",
]
REQ = {"bg": 0.03, "sg": 1.0, "mg": 15.0, "ba": 50.0, "sa": 1.0, "ma": 10.0}  # conventions.md


@pytest.fixture(scope="module", autouse=True)
def private_home(tmp_path_factory):
    """Keep rerun's analytics/config files out of the real home directory."""
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HOME", str(home))
        for var, sub in (
            ("XDG_CONFIG_HOME", ".config"),
            ("XDG_DATA_HOME", ".local/share"),
            ("XDG_CACHE_HOME", ".cache"),
        ):
            mp.setenv(var, str(home / sub))
        yield home


# ---------------------------------------------------------------------------
# Reading back, with rerun's reader only


def world_attitude(rec, t: float) -> np.ndarray:
    """C_b^n of the IMU at time t: the transforms along the gimbal path, latest at or before t."""
    C = np.eye(3)
    for entity in GIMBAL_PATH:
        b = batch_with(rec, entity, "Transform3D:mat3x3")
        M = matrices(b)
        if "time" in b.schema.names:
            k = np.searchsorted(times_of(b), t, side="right") - 1
            assert k >= 0
            M = M[k : k + 1]
        C = C @ M[0]
    return C


# ---------------------------------------------------------------------------
# Fixtures: one short simulated run (Table 2 errors, noise) and a result near its truth


@pytest.fixture(scope="module")
def sim():
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.definition import load_sequence
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    seq = load_sequence("paper-9pos")
    run, truth = simulate(
        seq,
        SimConfig(math.radians(40.0), sample_rate_hz=RATE_HZ),
        ErrorModel.from_table2(),
        load_profile("navigation"),
        options=SimOptions(seed=3),
    )
    assert run.n_samples == N_SAMPLES
    return seq, run, truth


def requirement_si(name: str) -> float:
    deg = math.pi / 180
    si = {"bg": deg / 3600, "sg": 1e-6, "mg": deg / 3600, "ba": 9.80665e-6, "sa": 1e-6, "ma": deg / 3600}[
        name[:2]
    ]
    return REQ[name[:2]] * si


@pytest.fixture(scope="module")
def result(sim):
    """A result 0.5 sigma off the truth with sigma = 0.3 x requirement (3 sigma / req = 0.9)."""
    from calib.calibration.result import CalibrationResult

    seq, run, truth = sim
    req = np.array([requirement_si(n) for n in SPEC_NAMES])
    sigma = 0.3 * req
    return CalibrationResult(
        values=truth.errors.values + 0.5 * sigma,
        sigma=sigma,
        C_b_n0=attitude("east", "up", "south"),
        converged=True,
        iterations=3,
        residual_rms_mps=1e-4,
        profile="navigation",
        chi2_per_dof=1.0,
        correlation=np.eye(21),
    )


@pytest.fixture(scope="module")
def recorded(sim, result, tmp_path_factory):
    from viz.record import record_run

    seq, run, truth = sim
    path = tmp_path_factory.mktemp("rec") / "run.rrd"
    summary = record_run(run, path, review_run(run, result), sequence=seq, result=result, truth=truth)
    return path, summary, read_back(path)


# ---------------------------------------------------------------------------
# Run recording


def test_entities_present(recorded):
    path, summary, rec = recorded
    for entity in [
        "about",
        "events",
        "world",
        "world/enu",
        "world/gravity",
        "world/label",
        *GIMBAL_PATH,
        "world/base/gimbal/outer/middle/inner/imu",
        "world/base/gimbal/outer/middle/inner/imu/axes",
        "signals/gyro_dps",
        "signals/accel_mps2",
        "residuals/before/velocity_mps",
        "residuals/after/velocity_mps",
        "attitude/gimbal_deg",
        "attitude/nav_minus_gimbal_arcsec",
        "sequence/position",
        "results/ratio",
        "results/error_over_requirement",
        "results/error_over_sigma",
        "results/correlation",
        "results/table",
    ]:
        assert entity in rec, entity
        assert entity in summary.entities, entity
    assert "encoders" in summary.scene_source and "truth" in summary.mount_source


def test_residuals_full_rate_one_row_per_sample(recorded, sim):
    _, summary, rec = recorded
    run = sim[1]
    for stage in ("before", "after"):
        t, v = scalars(rec, f"residuals/{stage}/velocity_mps")
        assert v.shape == (N_SAMPLES, 3)
        assert summary.entities[f"residuals/{stage}/velocity_mps"] == N_SAMPLES
        # time line = seconds since the first sample starts; the run starts at 0.
        np.testing.assert_allclose(t, run.time_s, atol=1e-9)
    # After compensating with a result 0.5 sigma off the truth the velocity stays small;
    # before, Table 2's 3 deg/h gyro biases drive it far away.
    _, after = scalars(rec, "residuals/after/velocity_mps")
    _, before = scalars(rec, "residuals/before/velocity_mps")
    assert np.abs(after).max() < 0.5
    assert np.abs(before).max() > 10 * np.abs(after).max()


def test_attitude_at_every_rest_position_matches_table1(recorded):
    _, _, rec = recorded
    for row in table1_positions():
        k = int(row["position"])
        start, end = rest_window(k)
        C = world_attitude(rec, 0.5 * (start + end))
        expected = attitude(row["pre_x"], row["pre_y"], row["pre_z"])
        np.testing.assert_allclose(C, expected, atol=1e-6, err_msg=f"position {k}")


def test_attitude_at_position_3(recorded):
    """Table 1, position 3: X north, Y west, Z up."""
    _, _, rec = recorded
    start, end = rest_window(3)
    expected = np.column_stack([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    for t in (start + 1.0, 0.5 * (start + end), end - 1.0):
        np.testing.assert_allclose(world_attitude(rec, t), expected, atol=1e-6)


def test_flip_is_drawn_smoothly(recorded):
    """Inside flip 2 (about Y, the inner gimbal) the transforms are at most ~2 deg apart."""
    _, _, rec = recorded
    b = batch_with(rec, "world/base/gimbal/outer/middle/inner", "Transform3D:mat3x3")
    t, M = times_of(b), matrices(b)
    a, z = rest_window(2)[1], rest_window(3)[0]
    sel = (t >= a) & (t <= z)
    angle = np.degrees(np.arctan2(M[sel, 0, 2], M[sel, 0, 0]))
    assert sel.sum() >= 45
    assert np.abs(np.diff(angle)).max() <= 2.5
    assert angle[0] == pytest.approx(0.0, abs=1.5) and angle[-1] == pytest.approx(90.0, abs=1.5)


def test_signals_decimated_and_physical(recorded, sim):
    _, _, rec = recorded
    run = sim[1]
    t, gyro = scalars(rec, "signals/gyro_dps")
    _, acc = scalars(rec, "signals/accel_mps2")
    assert len(t) == N_SAMPLES // 2  # 40 Hz shown as 20 Hz block means
    # Each row is the mean over two samples: sum(increments) / sum(dt), at the pair's middle.
    pairs = lambda x: x.reshape(-1, 2, 3).sum(axis=1) / (2.0 / RATE_HZ)  # noqa: E731
    np.testing.assert_allclose(t, run.time_s[1::2] - 1.0 / RATE_HZ, atol=1e-9)
    np.testing.assert_allclose(acc, pairs(run.dv_mps), rtol=1e-9)  # dt from the time stamps
    np.testing.assert_allclose(gyro, np.degrees(pairs(run.dtheta_rad)), rtol=1e-9, atol=1e-12)
    # Physics: |f| = g at rest (Table 2's mg-level biases and 100-ppm-level scale factors aside).
    g = normal_gravity(math.radians(40.0), 0.0)
    rest = (t > 10) & (t < 170)
    np.testing.assert_allclose(np.linalg.norm(acc[rest], axis=1), g, rtol=5e-3)
    flip1 = (t > 181) & (t < 188)  # about body Z at +10 deg/s
    np.testing.assert_allclose(gyro[flip1, 2], 10.0, atol=0.01)
    about = text_of(rec, "about")
    assert "DECIMATED" in about and "FULL rate" in about and str(N_SAMPLES) in about
    assert run.n_samples == N_SAMPLES


def test_positions_and_flips_as_text(recorded):
    _, _, rec = recorded
    b = rec["events"][0]
    rows = [x[0] for x in b.column("TextLog:text").to_pylist()]
    # Long events are wrapped into continuation rows (indented, at the same time): one
    # first row per rest and per flip.
    first = [not x.startswith("  ") for x in rows]
    t, text = times_of(b)[first], [x for x, f in zip(rows, first, strict=True) if f]
    assert len(text) == 2 * N_POS - 1
    k = text.index(next(x for x in text if x.startswith("position 3:")))
    assert t[k] == pytest.approx(rest_window(3)[0], abs=1e-9)
    assert "X north, Y west, Z up" in text[k]
    flips = [(ti, x) for ti, x in zip(t, text, strict=True) if x.startswith("flip")]
    assert [ti for ti, _ in flips] == pytest.approx([rest_window(i)[1] for i in range(1, N_POS)])
    assert "about body Y by +90 deg" in flips[1][1]
    # The position marker series steps through 1..9 and is 0 while turning.
    ts, pos = scalars(rec, "sequence/position")
    for i in range(1, N_POS + 1):
        start, end = rest_window(i)
        inside = (ts > start + 1) & (ts < end - 1)
        assert np.all(pos[inside, 0] == i)
    assert np.all(pos[(ts > 181) & (ts < 188), 0] == 0)


def test_result_bars(recorded):
    _, _, rec = recorded
    np.testing.assert_allclose(bars(rec, "results/ratio"), 0.9, rtol=1e-6)
    np.testing.assert_allclose(bars(rec, "results/error_over_requirement"), 0.15, rtol=1e-6)
    np.testing.assert_allclose(bars(rec, "results/error_over_sigma"), 0.5, rtol=1e-6)
    table = text_of(rec, "results/table")
    for name in SPEC_NAMES:
        assert f"| {name} |" in table
    corr = tensor(batch_with(rec, "results/correlation", "Tensor:data"), "Tensor:data")
    np.testing.assert_allclose(corr, np.eye(21))


def test_no_wall_clock_timeline(recorded):
    """Only the explicit 'time' timeline: nothing logged per sample with log()."""
    _, _, rec = recorded
    indexes = set()
    for _entity, batches in rec.items():
        for b in batches:
            for f in b.schema:
                if (f.metadata or {}).get(b"rerun:kind") == b"index":
                    indexes.add(f.name)
    assert indexes == {"time"}


def test_blueprint_is_stored(recorded):
    from rerun.chunk import RrdReader

    reader = RrdReader(str(recorded[0]))
    (blueprint,) = reader.blueprints()
    views = {c.entity_path for c in reader.stream(store=blueprint) if c.entity_path.startswith("/view/")}
    assert len(views) >= 10  # 3D, text log, 7 time series, 2 bar charts, 3 tabs


def test_recording_is_reproducible(sim, result, recorded, tmp_path):
    """Same inputs, same content (rerun's row ids, drawn from the clock, excepted)."""
    from rerun.chunk import RrdReader

    from viz.record import record_run

    seq, run, truth = sim
    again = tmp_path / "again.rrd"
    record_run(run, again, review_run(run, result), sequence=seq, result=result, truth=truth)
    a, b = recorded[2], read_back(again)
    assert a.keys() == b.keys()
    for entity in a:
        ta = [x.drop_columns(["rerun.controls.RowId"]) for x in a[entity]]
        tb = [x.drop_columns(["rerun.controls.RowId"]) for x in b[entity]]
        key = lambda x: x.schema.names  # noqa: E731
        assert sorted(ta, key=key) == sorted(tb, key=key), entity
    ids = [RrdReader(str(p)).recordings()[0].recording_id for p in (recorded[0], again)]
    assert ids[0] == ids[1]


# ---------------------------------------------------------------------------
# Other sources of the gimbal angles


def test_scene_from_sequence_without_encoders(sim, tmp_path):
    from dataclasses import replace

    from viz.record import record_run

    seq, run, truth = sim
    bare = replace(run, gimbal_deg=None)
    summary = record_run(bare, tmp_path / "seq.rrd", review_run(bare), sequence=seq)
    assert summary.scene_source.startswith("sequence")
    rec = read_back(tmp_path / "seq.rrd")
    for row in table1_positions():
        start, end = rest_window(int(row["position"]))
        np.testing.assert_allclose(
            world_attitude(rec, 0.5 * (start + end)),
            attitude(row["pre_x"], row["pre_y"], row["pre_z"]),
            atol=1e-6,
        )
    assert "residuals/after/velocity_mps" not in rec and "results/ratio" not in rec


def test_scene_from_navigation(sim, result, tmp_path):
    """No encoders, no sequence: the calibrated navigation attitude drives the scene."""
    from dataclasses import replace

    from viz.record import record_run

    seq, run, truth = sim
    bare = replace(run, gimbal_deg=None, meta={k: v for k, v in run.meta.items() if k != "sequence"})
    summary = record_run(bare, tmp_path / "nav.rrd", review_run(bare, result), result=result)
    assert summary.scene_source.startswith("navigation attitude after calibration")
    rec = read_back(tmp_path / "nav.rrd")
    for row in table1_positions():
        start, end = rest_window(int(row["position"]))
        np.testing.assert_allclose(
            world_attitude(rec, 0.5 * (start + end)),
            attitude(row["pre_x"], row["pre_y"], row["pre_z"]),
            atol=1e-3,
        )
    text = [x[0] for x in rec["events"][0].column("TextLog:text").to_pylist()]
    assert sum(x.startswith("flip") for x in text) == N_POS - 1
    assert sum(x.startswith("position") for x in text) == N_POS


# ---------------------------------------------------------------------------
# Analysis recording


def nominal_analysis(seq):
    """The analysis of ``seq`` at the nominal mounting (navigation profile, 40 deg)."""
    from seqdesign.analysis import analyze

    return analyze(seq, "navigation", latitude_deg=40.0, tolerance_deg=0.0)


def test_analysis_recording(tmp_path):
    from calib.sequence.definition import load_sequence
    from viz.record import record_analysis

    seq = load_sequence("paper-9pos")
    analysis = nominal_analysis(seq)
    obs = analysis.robustness.nominal
    record_analysis(analysis, tmp_path / "analysis.rrd")
    rec = read_back(tmp_path / "analysis.rrd")
    corr = tensor(batch_with(rec, "analysis/correlation", "Tensor:data"), "Tensor:data")
    assert corr.shape == (21, 21)
    np.testing.assert_allclose(np.diag(corr), 1.0, atol=1e-12)
    np.testing.assert_allclose(corr, corr.T, atol=1e-12)
    i, j = SPEC_NAMES.index("sgy"), SPEC_NAMES.index("mazx")
    assert corr[i, j] < -0.9  # the README's most correlated pair
    np.testing.assert_allclose(bars(rec, "analysis/ratio"), obs.ratio, rtol=1e-12)
    for row in table1_positions():
        k = int(row["position"])
        M = matrices(batch_with(rec, f"positions/p{k}", "Transform3D:mat3x3"))[0]
        np.testing.assert_allclose(M, attitude(row["pre_x"], row["pre_y"], row["pre_z"]), atol=1e-6)
        start, end = rest_window(k)
        np.testing.assert_allclose(
            world_attitude(rec, 0.5 * (start + end)),
            attitude(row["pre_x"], row["pre_y"], row["pre_z"]),
            atol=1e-6,
        )
    assert "sgy" in text_of(rec, "analysis/table")


# ---------------------------------------------------------------------------
# Command line


def _write_run(sim, result, folder: Path, sha_of_run: bool = True) -> Path:
    from dataclasses import replace

    from calib.io.files import sha256_file
    from calib.runlog import write_run
    from calib.sim.truth import write_truth

    seq, run, truth = sim
    path = folder / "run.npz"
    write_run(run, path)
    write_truth(folder / "run.truth.toml", truth)
    sha = sha256_file(path) if sha_of_run else "0" * 64
    replace(result, provenance={"run_sha256": sha}).save(folder / "run.result.toml")
    return path


def test_cli_defaults_beside_the_run(sim, result, tmp_path):
    from seqdesign.cli.view import view

    run_path = _write_run(sim, result, tmp_path)
    res = CliRunner().invoke(view, [str(run_path), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["rrd"] == str(tmp_path / "run.rrd")
    assert doc["result"] == str(tmp_path / "run.result.toml")
    assert doc["truth"] == str(tmp_path / "run.truth.toml")
    assert doc["sequence"] == "paper-9pos"
    assert doc["entities"]["residuals/after/velocity_mps"] == N_SAMPLES
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "run.npz",
        "run.result.toml",
        "run.rrd",
        "run.truth.toml",
    ]
    rec = read_back(tmp_path / "run.rrd")
    np.testing.assert_allclose(bars(rec, "results/error_over_requirement"), 0.15, rtol=1e-6)


def test_cli_skips_a_result_of_another_run(sim, result, tmp_path):
    from seqdesign.cli.view import view

    run_path = _write_run(sim, result, tmp_path, sha_of_run=False)
    res = CliRunner().invoke(view, [str(run_path), "-o", str(tmp_path / "x.rrd"), "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["result"] is None
    assert "different run" in res.stderr
    # Given explicitly, the same result is refused and nothing is written.
    res = CliRunner().invoke(
        view, [str(run_path), "--result", str(tmp_path / "run.result.toml"), "-o", str(tmp_path / "y.rrd")]
    )
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert not (tmp_path / "y.rrd").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["missing.npz"],
        ["run.npz", "-o", "out.txt"],
        ["run.npz", "--sequence", "no-such-sequence"],
        ["run.npz", "--result", "missing.result.toml"],
        ["run.npz", "-o", "no/such/dir/run.rrd"],
    ],
)
def test_cli_bad_input_one_line_nothing_written(sim, result, tmp_path, monkeypatch, args):
    from seqdesign.cli.view import view

    _write_run(sim, result, tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(view, args)
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # no .rrd, no temporary file


def test_failure_midway_leaves_old_file_untouched(sim, tmp_path, monkeypatch):
    import viz.run
    from viz.record import record_run

    seq, run, truth = sim
    target = tmp_path / "run.rrd"
    target.write_bytes(b"old")

    def boom(*a, **k):
        raise KeyboardInterrupt

    # Interrupted half-way through logging (the estimation work is done before, in calib.fit.replay).
    monkeypatch.setattr(viz.run, "block_means", boom)
    with pytest.raises(KeyboardInterrupt):
        record_run(run, target, review_run(run), sequence=seq)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["run.rrd"]


def test_nothing_written_to_the_real_home(private_home):
    assert Path.home() == private_home


# ---------------------------------------------------------------------------
# Readable as it opens (issue 17, point 6): names on the bars and the matrix, rows not cut,
# the velocity error after calibration against its predicted noise envelope


def labels_of(rec, entity, archetype):
    return batch_with(rec, entity, f"{archetype}:labels").column(f"{archetype}:labels").to_pylist()[0]


def positions_of(rec, entity, archetype="Points2D", column="positions"):
    b = batch_with(rec, entity, f"{archetype}:{column}")
    return b.column(f"{archetype}:{column}").to_pylist()[0]


@pytest.mark.parametrize(
    "entity", ["results/ratio", "results/error_over_requirement", "results/error_over_sigma"]
)
def test_result_bars_carry_the_parameter_names(recorded, entity):
    """Each bar is a 2D line in row i (spec order) labelled with parameter i's name; the names
    and the values are written beside the bars; bar lengths are proportional to the values."""
    _, _, rec = recorded
    values = bars(rec, entity)
    assert labels_of(rec, entity, "LineStrips2D") == SPEC_NAMES
    assert labels_of(rec, f"{entity}/names", "Points2D") == SPEC_NAMES
    shown = [float(x) for x in labels_of(rec, f"{entity}/values", "Points2D")]
    np.testing.assert_allclose(shown, values, atol=0.005)  # printed with two decimals
    strips = np.array(positions_of(rec, entity, "LineStrips2D", "strips"), dtype=float)
    assert strips.shape == (21, 2, 2)
    rows = np.repeat(np.arange(21)[:, None] + 0.5, 2, axis=1)
    np.testing.assert_allclose(strips[:, :, 1], rows)  # row i = parameter i, horizontal
    np.testing.assert_allclose(strips[:, 0, 0], 0.0)
    scale = strips[:, 1, 0] / values
    np.testing.assert_allclose(scale, scale[0], rtol=1e-6)
    assert scale[0] > 0
    # The names sit left of the zero line, each on its bar's row.
    names_xy = np.array(positions_of(rec, f"{entity}/names"), dtype=float)
    assert np.all(names_xy[:, 0] < 0)
    np.testing.assert_allclose(np.diff(names_xy[:, 1]), 1.0, atol=1e-5)  # float32 positions


def test_correlation_matrix_carries_the_parameter_names(recorded):
    _, _, rec = recorded
    assert labels_of(rec, "results/correlation/rows", "Points2D") == SPEC_NAMES
    assert labels_of(rec, "results/correlation/columns", "Points2D") == SPEC_NAMES
    rows_xy = np.array(positions_of(rec, "results/correlation/rows"), dtype=float)
    cols_xy = np.array(positions_of(rec, "results/correlation/columns"), dtype=float)
    assert np.all(rows_xy[:, 0] < 0) and np.all(cols_xy[:, 1] < 0)  # left of and above the image
    np.testing.assert_allclose(cols_xy[:, 0], np.arange(21) + 0.5)  # column j over pixel j
    # The image: one pixel per pair; the fixture's correlation is the identity, so the
    # diagonal is the +1 colour and every other pixel the 0 colour (white).
    b = batch_with(rec, "results/correlation/image", "Image:buffer")
    fmt = b.column("Image:format").to_pylist()[0][0]
    assert (fmt["width"], fmt["height"]) == (21, 21)
    img = np.array(b.column("Image:buffer").to_pylist()[0][0], dtype=np.uint8).reshape(21, 21, 3)
    off = ~np.eye(21, dtype=bool)
    assert np.all(img[off] == 255)
    diag = img[np.arange(21), np.arange(21)]
    assert np.all(diag == diag[0]) and diag[0, 0] > 150 and diag[0, 1] < 100  # red
    cells = labels_of(rec, "results/correlation/cells", "Points2D")
    assert cells[SPEC_NAMES.index("sgy") * 21 + SPEC_NAMES.index("sgy")] == "sgy / sgy: +1.000"


def test_analysis_bars_and_matrix_carry_the_names(tmp_path):
    from calib.sequence.definition import load_sequence
    from viz.record import record_analysis

    seq = load_sequence("paper-9pos")
    analysis = nominal_analysis(seq)
    record_analysis(analysis, tmp_path / "analysis.rrd")
    rec = read_back(tmp_path / "analysis.rrd")
    for entity in ("analysis/ratio", "analysis/sigma_over_requirement"):
        assert labels_of(rec, entity, "LineStrips2D") == SPEC_NAMES
        assert labels_of(rec, f"{entity}/names", "Points2D") == SPEC_NAMES
    assert labels_of(rec, "analysis/correlation/rows", "Points2D") == SPEC_NAMES
    assert labels_of(rec, "analysis/correlation/columns", "Points2D") == SPEC_NAMES
    # The README's most correlated pair, sgy/mazx (rho < -0.9), is a blue pixel.
    i, j = SPEC_NAMES.index("sgy"), SPEC_NAMES.index("mazx")
    b = batch_with(rec, "analysis/correlation/image", "Image:buffer")
    img = np.array(b.column("Image:buffer").to_pylist()[0][0], dtype=np.uint8).reshape(21, 21, 3)
    assert img[i, j, 2] > 150 and img[i, j, 0] < 100
    cell = labels_of(rec, "analysis/correlation/cells", "Points2D")[i * 21 + j]
    assert cell.startswith("sgy / mazx: -0.9")


def test_event_rows_are_short_enough_for_the_view(recorded):
    """The events view is ~480 px of message at 1920 px: 60 characters fit (docs/viewer.png)."""
    _, _, rec = recorded
    rows = [x[0] for x in rec["events"][0].column("TextLog:text").to_pylist()]
    assert max(len(x) for x in rows) <= 60
    assert any(x.startswith("  gimbal outer") for x in rows)  # the wrapped part is still there


def test_noise_envelope_in_the_recording(recorded):
    """+/-3 sigma of the navigation profile: zero at the start and, early in the first rest
    (Earth-rate terms omega_ie t < 1e-2), 3 sqrt(VRW^2 t + g^2 ARW^2 t^3 / 3) horizontally
    (VRW directly, ARW through the tilt) and 3 VRW sqrt(t) vertically."""
    from conftest import ARW_NAV, VRW_NAV

    _, _, rec = recorded
    t, env = scalars(rec, "residuals/after/noise_3sigma_mps")
    assert env.shape[1] == 6
    np.testing.assert_allclose(env[:, 3:], -env[:, :3])
    np.testing.assert_allclose(env[0], 0.0)
    assert t[0] == 0.0
    g = normal_gravity(math.radians(40.0), 0.0)
    k = int(np.argmin(np.abs(t - 100.0)))
    tk = t[k]
    horizontal = 3.0 * math.sqrt(VRW_NAV**2 * tk + g**2 * ARW_NAV**2 * tk**3 / 3.0)
    np.testing.assert_allclose(env[k, :2], horizontal, rtol=1e-2)
    np.testing.assert_allclose(env[k, 2], 3.0 * VRW_NAV * math.sqrt(tk), rtol=1e-2)
    assert np.all(np.diff(env[:, 0]) >= 0)  # an unbounded random walk only grows


@pytest.mark.slow
def test_noise_sigma_matches_monte_carlo_spread():
    """40 noise-only runs (no IMU errors) navigated from their true initial attitude: the RMS
    velocity error matches velocity_noise_sigma. The RMS of 40 draws scatters by 1/sqrt(80)
    = 11 % (1 sigma): the band [0.67, 1.33] is 3 of those."""
    from calib.fit.replay import velocity_noise_sigma
    from calib.model.error_model import ErrorModel
    from calib.nav.strapdown import navigate
    from calib.noise.profiles import load_profile
    from calib.sequence.definition import load_sequence
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    seq, lat = load_sequence("paper-9pos"), math.radians(40.0)
    cfg, profile = SimConfig(lat, sample_rate_hz=10.0), load_profile("navigation")
    v = []
    for seed in range(40):
        run, truth = simulate(seq, cfg, ErrorModel(np.zeros(21)), profile, options=SimOptions(seed=seed))
        nav = navigate(
            run.dtheta_rad, run.dv_mps, run.time_s, truth.R_setup @ seq.C_start, Site(lat, cfg.gravity)
        )
        v.append(nav.v_n)
    v = np.array(v)
    t = nav.time_s - nav.time_s[0]
    sigma = velocity_noise_sigma(np.full(int(round(t[-1])), 1.0), Site(lat, cfg.gravity), profile)
    for when in (300, 900, 1690):
        rms = np.sqrt((v[:, int(np.argmin(np.abs(t - when)))] ** 2).mean(axis=0))
        ratio = rms / sigma[when]
        assert np.all((ratio > 0.67) & (ratio < 1.33)), (when, ratio)


@pytest.mark.slow
def test_calibrated_velocity_stays_inside_the_envelope():
    """Noisy runs (Table 2 errors, random mounting) calibrated with their own profile: the
    velocity error after calibration is inside the predicted +/-3 sigma >= 99 % of the time on
    every axis (measured: 99.99 % pooled over these 5 runs). The fit absorbs part of the noise,
    so the residual sits well inside; the noise-only spread is checked above."""
    from calib.calibration.entry import calibrate
    from calib.model.error_model import ErrorModel
    from calib.noise.profiles import load_profile
    from calib.sequence.definition import load_sequence
    from calib.sequence.kinematics import SimConfig
    from calib.sim.gimbal_run import SimOptions, simulate

    seq = load_sequence("paper-9pos")
    inside = []
    for seed in range(5):
        run, _ = simulate(
            seq,
            SimConfig(math.radians(40.0), sample_rate_hz=10.0),
            ErrorModel.from_table2(),
            load_profile("navigation"),
            options=SimOptions(seed=seed, random_setup_deg=3.0),
        )
        review = review_run(run, calibrate(run, "navigation", sequence=seq))
        assert review.noise_profile == "navigation"
        t = run.time_s - review.t0
        sigma = np.column_stack(
            [np.interp(t, review.noise_time, review.noise_sigma_v[:, i]) for i in range(3)]
        )
        inside.append(np.abs(review.after.v_n[1:]) <= 3.0 * sigma)
    fraction = np.concatenate(inside).mean(axis=0)
    assert np.all(fraction >= 0.99), fraction


def test_envelope_falls_back_to_the_default_profile(sim, result):
    from dataclasses import replace

    run = sim[1]
    review = review_run(run, replace(result, profile="no-such-profile"))
    assert review.noise_profile == "navigation"
    assert any("no-such-profile" in n and "navigation" in n for n in review.notes)


def test_spawn_without_a_display_says_so_and_exits_3(sim, result, tmp_path, monkeypatch):
    import seqdesign.cli.view as cli_view

    run_path = _write_run(sim, result, tmp_path)
    spawned = []
    monkeypatch.setattr(cli_view, "_spawn_viewer", spawned.append)
    monkeypatch.setattr(cli_view.sys, "platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    res = CliRunner().invoke(cli_view.view, [str(run_path), "--spawn"])
    assert res.exit_code == 3, res.output
    assert "Traceback" not in res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "no display" in lines[0] and "run.rrd" in lines[0]
    assert (tmp_path / "run.rrd").stat().st_size > 0 and not spawned
    read_back(tmp_path / "run.rrd")  # a complete recording
    # With a display the viewer is started and the command succeeds.
    monkeypatch.setenv("WAYLAND_DISPLAY", "wayland-0")
    res = CliRunner().invoke(cli_view.view, [str(run_path), "--spawn", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["viewer"] == "spawned" and len(spawned) == 1


def test_display_available():
    from seqdesign.cli.view import display_available

    assert not display_available({}, "linux")
    assert not display_available({"DISPLAY": ""}, "linux")
    assert display_available({"DISPLAY": ":0"}, "linux")
    assert display_available({"WAYLAND_DISPLAY": "wayland-0"}, "linux")
    assert display_available({}, "darwin") and display_available({}, "win32")


def test_rank_deficient_analysis_names_the_unobservable_bars(tmp_path):
    """One Z flip cannot observe all 21: their bars are empty and say so."""
    from calib.sequence.definition import load_sequence
    from viz.record import record_analysis

    path = tmp_path / "onez.toml"
    path.write_text(
        'name = "onez"\nstart = ["east", "up", "south"]\ninitial_dwell_s = 60\n'
        '[[step]]\naxis = "Z"\nangle_deg = 90\ndwell_s = 60\n'
    )
    seq = load_sequence(str(path))
    analysis = nominal_analysis(seq)
    obs = analysis.robustness.nominal
    assert obs.rank < 21
    record_analysis(analysis, tmp_path / "onez.rrd")
    rec = read_back(tmp_path / "onez.rrd")
    assert labels_of(rec, "analysis/ratio/names", "Points2D") == SPEC_NAMES
    shown = labels_of(rec, "analysis/ratio/values", "Points2D")
    missing = ~np.isfinite(obs.ratio)
    assert missing.any()
    assert [x == "unobservable" for x in shown] == list(missing)
    strips = np.array(positions_of(rec, "analysis/ratio", "LineStrips2D", "strips"), dtype=float)
    np.testing.assert_allclose(strips[missing, 1, 0], 0.0)


# ---------------------------------------------------------------------------
# A result judged against other requirements than the paper's is drawn against its own


def test_view_draws_a_result_against_its_own_requirements(tmp_path, monkeypatch):
    """simulate -> calibrate --requirements mems -> view: the bars are 3 sigma / the MEMS
    requirement and |error| / the MEMS requirement, the expected values built from the
    result file's sigmas, the truth file and calib/data/requirements/mems.toml."""
    import tomllib

    from seqdesign.cli import main

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    for args in (
        ["simulate", "paper-9pos", "--table2", "--seed", "1", "--sample-rate-hz", "20", "-o", "run.npz"],
        ["calibrate", "run.npz", "--requirements", "mems"],
        ["view", "run.npz", "--result", "run.result.toml", "-o", "x.rrd"],
    ):
        res = runner.invoke(main, args)
        assert res.exit_code == 0, (args, res.output)
    mems_file = REPO / "calib" / "data" / "requirements" / "mems.toml"
    mems = tomllib.loads(mems_file.read_text())["requirements"]
    saved = tomllib.loads((tmp_path / "run.result.toml").read_text())["parameters"]
    truth = tomllib.loads((tmp_path / "run.truth.toml").read_text())["errors"]
    req = np.array([mems[n] for n in SPEC_NAMES])
    sigma = np.array([saved[n]["sigma"] for n in SPEC_NAMES])
    error = np.array([saved[n]["value"] - truth[n] for n in SPEC_NAMES])
    assert not np.allclose(req, [REQ[n[:2]] for n in SPEC_NAMES])  # not the paper's
    rec = read_back(tmp_path / "x.rrd")
    np.testing.assert_allclose(bars(rec, "results/ratio"), 3.0 * sigma / req, rtol=1e-6)
    np.testing.assert_allclose(bars(rec, "results/error_over_requirement"), np.abs(error) / req, rtol=1e-6)
    table = text_of(rec, "results/table")
    assert "requirements mems" in table
    k = SPEC_NAMES.index("bgx")
    row = next(x for x in table.splitlines() if x.startswith(f"| {k} | bgx |"))
    assert f"| {3.0 * sigma[k] / req[k]:.2f} |" in row


def test_analysis_recording_shows_what_analyze_prints(tmp_path):
    """Over a mounting box, analyze prints each parameter's worst sigma and ratio: the recording's
    bars and table hold those figures, and say which mounting the correlation matrix, the scene
    and the gallery are drawn at (the worst; its correlated pairs are the JSON's)."""
    from seqdesign.cli import main

    out = tmp_path / "a.rrd"
    res = CliRunner().invoke(main, ["analyze", "paper-9pos", "--view", str(out), "--json"])
    assert res.exit_code == 0, res.output
    doc = json.loads(res.stdout)
    assert doc["tolerance_deg"] == 3.0
    entries = [doc["parameters"][n] for n in SPEC_NAMES]
    ratio = np.array([e["ratio"] for e in entries])
    assert np.any(ratio > np.array([e["ratio_nominal"] for e in entries]))  # the box matters
    rec = read_back(out)
    np.testing.assert_allclose(bars(rec, "analysis/ratio"), ratio, rtol=1e-12)
    np.testing.assert_allclose(
        bars(rec, "analysis/sigma_over_requirement"),
        [e["sigma"] / e["requirement"] for e in entries],
        rtol=1e-12,
    )
    table = text_of(rec, "analysis/table")
    for k, (name, e) in enumerate(zip(SPEC_NAMES, entries, strict=True)):
        row = next(x for x in table.splitlines() if x.startswith(f"| {k} | {name} |"))
        assert f"| {e['sigma']:.3g} | {e['requirement']:g} | {e['ratio']:.2f}" in row
    assert f"worst 3 sigma / requirement: {doc['worst']['ratio']:.2f} ({doc['worst']['name']})" in table
    mounting = str(np.round(doc["worst_setup_deg"], 3).tolist())
    assert "each parameter's worst over +-3 deg" in table
    assert mounting in table and mounting in text_of(rec, "about")
    cells = labels_of(rec, "analysis/correlation/cells", "Points2D")
    for pair in doc["correlated_pairs"]:
        i, j = SPEC_NAMES.index(pair["a"]), SPEC_NAMES.index(pair["b"])
        assert cells[i * 21 + j] == f"{pair['a']} / {pair['b']}: {pair['rho']:+.3f}"
