"""What a careful user trips over with files (issue 39): an output over an input, long messages.

Each is run as a user runs it, the CLI in a process of its own.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

# What the tool prints is bounded (issue 39): a count, then the first few.
MAX_MESSAGE = 400


def cli(*args, cwd=None) -> subprocess.CompletedProcess:
    """``seqdesign ARGS`` in a process of its own: exit code, stdout and stderr as a user sees them."""
    return subprocess.run(
        [sys.executable, "-m", "seqdesign.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd
    )


def one_line_refusal(res: subprocess.CompletedProcess, *parts: str) -> str:
    """The single ``error:`` line of a refused command, holding each of ``parts``."""
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("error: ")]
    assert len(lines) == 1, res.stderr
    for part in parts:
        assert part in lines[0], (part, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    """A short simulated run (NPZ) and the correction its calibration writes."""
    d = tmp_path_factory.mktemp("logged")
    res = cli("simulate", "paper-9pos", "--sample-rate-hz", "10", "--seed", "3", "-o", d / "run.npz")
    assert res.returncode == 0, res.stderr
    res = cli("calibrate", d / "run.npz", "-o", d / "run.result.toml", "--correction", d / "c.toml")
    assert res.returncode == 0, res.stderr
    return d


# ---------------------------------------------------------------------------
# 1. An output never overwrites an input


@pytest.mark.parametrize("spelling", ["run.npz", "./run.npz", "../{d}/run.npz"])
def test_calibrate_refuses_to_write_its_result_over_the_log(logged, spelling):
    before = (logged / "run.npz").read_bytes()
    res = cli("calibrate", "run.npz", "-o", spelling.format(d=logged.name), cwd=logged)
    one_line_refusal(res, "-o", "same file as RUN", "another file name")
    assert (logged / "run.npz").read_bytes() == before


def test_calibrate_refuses_a_correction_over_the_log_or_the_result(logged):
    before = (logged / "run.npz").read_bytes()
    res = cli("calibrate", "run.npz", "-o", "new.toml", "--correction", "run.npz", cwd=logged)
    one_line_refusal(res, "--correction", "same file as RUN")
    res = cli("calibrate", "run.npz", "-o", "new.toml", "--correction", "new.toml", cwd=logged)
    one_line_refusal(res, "--correction", "same file as -o")
    assert (logged / "run.npz").read_bytes() == before and not (logged / "new.toml").exists()


def test_correct_refuses_to_write_over_the_log_or_its_correction(logged):
    before = {name: (logged / name).read_bytes() for name in ("run.npz", "c.toml")}
    one_line_refusal(cli("correct", "run.npz", "--correction", "c.toml", "-o", "run.npz", cwd=logged), "LOG")
    res = cli("correct", "run.npz", "--correction", "c.toml", "-o", "c.toml", cwd=logged)
    one_line_refusal(res, "--correction")
    assert {name: (logged / name).read_bytes() for name in before} == before


def test_an_output_beside_the_input_is_written(logged):
    res = cli("correct", "run.npz", "--correction", "c.toml", "-o", "run.corrected.npz", cwd=logged)
    assert res.returncode == 0, res.stderr
    assert (logged / "run.corrected.npz").exists()


# ---------------------------------------------------------------------------
# 2. Every message is bounded


def test_a_log_read_at_twice_its_rate_is_refused_in_one_short_line(tmp_path):
    # A 100 Hz log read as 200 Hz: every other sample looks lost, tens of thousands of places.
    res = cli("simulate", "paper-9pos", "--sample-rate-hz", "100", "--seed", "1", "-o", tmp_path / "r.csv")
    assert res.returncode == 0, res.stderr
    text = (tmp_path / "r.csv").read_text()
    (tmp_path / "r.csv").write_text("".join(ln for ln in text.splitlines(True) if "sample_rate_hz" not in ln))
    res = cli("calibrate", "r.csv", "--sample-rate-hz", "200", "-o", "r.toml", cwd=tmp_path)
    line = one_line_refusal(res, "sample(s) dropped", "--allow-gaps")
    assert len(line) <= MAX_MESSAGE, len(line)
    n_lost = int(line.split("sample(s) dropped")[0].split()[-1])
    assert n_lost > 1000  # half the samples of 28 min: counted, not listed
    assert max(map(len, res.stderr.splitlines())) <= MAX_MESSAGE
    assert not (tmp_path / "r.toml").exists()


# ---------------------------------------------------------------------------
# 15. A sequence key that would change the run is refused; a near miss is a real one

SEQUENCE = """name = "s"
start = ["east", "up", "south"]
{top}
[[step]]
axis = "Z"
angle_deg = 90
{step}
"""


@pytest.mark.parametrize(
    "top, step, key",
    [
        ("", "wait_s = 60", "step 1: key 'wait_s'"),  # a dwell under another name
        ("wait_s = 60", "dwell_s = 60", "key 'wait_s'"),
        ("", "dwell_s = 60\nnote = 'slow'", "step 1: key 'note'"),  # a step holds its motion alone
    ],
)
def test_a_sequence_key_that_would_change_the_run_is_refused(tmp_path, top, step, key):
    path = tmp_path / "s.toml"
    path.write_text(SEQUENCE.format(top=top, step=step))
    line = one_line_refusal(cli("show", path), key, "would change the run", "dwell_s")
    assert "did you mean" not in line


def test_an_informative_key_is_a_warning_and_gets_no_far_fetched_suggestion(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SEQUENCE.format(top='site = "Calgary"', step="dwell_s = 60"))
    res = cli("show", path)
    assert res.returncode == 0, res.stderr
    assert "'site' is not a sequence key; it is ignored" in res.stderr
    assert "did you mean" not in res.stderr


def test_a_near_miss_is_still_refused_naming_the_key_meant(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SEQUENCE.format(top="", step="dwel_s = 60"))
    one_line_refusal(cli("show", path), "did you mean 'dwell_s'")


# ---------------------------------------------------------------------------
# 3. The corrected log keeps the absolute time


def test_correct_keeps_the_epoch_of_a_log_stamped_in_unix_time(logged, tmp_path):
    epoch, rate = 1_700_000_000, 100.0
    stamps = [f"{epoch + k / rate:.6f}" for k in range(1, 501)]
    rows = [f"{t},0.0,0.0,7.3e-05,0.0,0.0,9.8" for t in stamps]
    log = tmp_path / "logger.csv"
    log.write_text(
        "# latitude_deg: 40\n# height_m: 0\n"
        "time_s,gyro_x_radps,gyro_y_radps,gyro_z_radps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n"
        + "\n".join(rows)
        + "\n"
    )
    out = tmp_path / "corrected.csv"
    res = cli("correct", log, "--correction", logged / "c.toml", "-o", out)
    assert res.returncode == 0, res.stderr
    header = dict(
        ln[2:].split(": ", 1) for ln in out.read_text().splitlines() if ln.startswith("# ") and ": " in ln
    )
    assert "time_origin_s" in header, header
    origin = float(header["time_origin_s"])
    body = [ln for ln in out.read_text().splitlines() if ln and not ln.startswith("#")][1:]
    for k in (0, 250, 499):  # each sample back at its own absolute time, to the stamps' microsecond
        assert abs(origin + float(body[k].split(",")[0]) - float(stamps[k])) < 2e-6
    assert "time_origin_s" in res.stderr
    # A log without epoch stamps gets no origin (its time_s is already what it says).
    res = cli("correct", logged / "run.npz", "--correction", logged / "c.toml", "-o", tmp_path / "o.csv")
    assert res.returncode == 0 and "time_origin_s" not in (tmp_path / "o.csv").read_text()


def test_a_long_message_is_cut_in_the_middle_between_words():
    from seqdesign.cli.tools import bounded

    text = " ".join(f"word{i:03d}" for i in range(100))  # 799 characters
    out = bounded(text)
    assert len(out) <= MAX_MESSAGE and out.startswith("word000") and out.endswith("word099")
    first, last = out.split(" ... ")
    assert set(first.split() + last.split()) <= set(text.split())  # no word left in part
