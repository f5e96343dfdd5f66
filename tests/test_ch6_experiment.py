"""examples/ch6_active_exploration.py: a reduced run end to end (columns, domains, safety, figures, summary).

Recognition is slow in this reproduction (a quick run is censored at the higher IC
thresholds), so the assertions are outcomes that must hold in any run, not crossings.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
import ch6_active_exploration as ch6  # noqa: E402

REQUIRED = ("seed", "presented", "strategy", "spc", "threshold", "im", "srt", "identity", "correct_first",
            "mean_correct_confidence", "mean_incorrect_confidence", "iterations", "refused_commands")


@pytest.fixture(scope="module")
def reduced(tmp_path_factory):
    out = tmp_path_factory.mktemp("ch6")
    assert ch6.main(["--quick", "--seeds", "1", "--iterations", "40", "--out", str(out)]) == 0
    with open(out / "ch6_runs.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    return out, rows


def test_csv_has_the_columns_and_one_row_per_run_and_threshold(reduced):
    _, rows = reduced
    assert set(REQUIRED) <= set(rows[0])
    # 1 seed x 3 strategies x 2 objects + 1 SPC-off run + the SPC-on run listed again, x 4 thresholds
    assert len(rows) == (6 + 2) * 4
    assert {r["strategy"] for r in rows} == {"default", "feh", "lsr"}
    assert {r["spc"] for r in rows} == {"on", "off"}
    assert {r["presented"] for r in rows} == {"box", "box_stack"}
    assert sorted({float(r["threshold"]) for r in rows}) == [100.0, 300.0, 600.0, 900.0]
    for r in rows:
        n = int(r["iterations"])
        assert n == 40 and r["stop_reason"] == "iterations"
        assert 0 <= float(r["srt"]) <= n and -n <= float(r["im"]) <= n
        assert r["identity"] in ("", "box", "box_stack")
        assert r["correct_first"] in ("True", "False")
        if r["correct_first"] == "True":
            assert r["identity"] == r["presented"]
        assert float(r["mean_correct_confidence"]) >= 0 and float(r["mean_incorrect_confidence"]) >= 0


def test_thresholds_are_evaluated_on_one_trace(reduced):
    _, rows = reduced
    by_run = {}
    for r in rows:
        by_run.setdefault((r["study"], r["seed"], r["presented"], r["strategy"], r["spc"]), []).append(r)
    for group in by_run.values():
        srt = [float(r["srt"]) for r in sorted(group, key=lambda r: float(r["threshold"]))]
        assert srt == sorted(srt)  # a higher threshold is never crossed earlier
        assert len({r["mean_correct_confidence"] for r in group}) == 1


def test_no_command_reached_the_arm_outside_the_envelope(reduced):
    _, rows = reduced
    assert all(int(r["commands_outside_envelope"]) == 0 for r in rows)
    assert sum(int(r["refused_commands"]) for r in rows if r["threshold"] == "100.0") > 0  # the floor refuses faces


def test_figures_and_summary(reduced):
    out, _ = reduced
    for name in ("fig6_2_spc_poses.png", "fig6_4_rc_ic.png", "fig6_6_confidence_spc.png", "fig6_7_im_threshold.png",
                 "fig6_8_im_strategy.png", "fig6_9_srt_strategy.png"):
        assert (out / name).stat().st_size > 1000
    text = (out / "ch6_summary.txt").read_text()
    for key in ("1. SPC", "2. LSR", "3. IC ~300", "Safety:", "outside the envelope 0"):
        assert key in text


@settings(max_examples=10, deadline=None)
@given(st.sampled_from([["--seeds", "0"], ["--iterations", "1"], ["--noise-scale", "nan"], ["--noise-scale", "-1"]]))
def test_bad_arguments_exit_2(tmp_path_factory, args):
    assert ch6.main(["--quick", "--out", str(tmp_path_factory.mktemp("bad")), *args]) == 2
