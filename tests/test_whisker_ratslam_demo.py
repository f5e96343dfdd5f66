"""The WhiskerRatSLAM demo (examples/whisker_ratslam_object.py) runs the real chain and writes its outputs."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "whisker_ratslam_object.py"
KEYS = {
    "median_position_error_m", "median_rotation_error_deg", "dr_median_position_error_m", "dr_median_rotation_error_deg",
    "step_translation_m", "step_rotation_deg", "relocalisations", "experiences", "whisks_per_s",
}


def _load():
    spec = importlib.util.spec_from_file_location("whisker_ratslam_object", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_quick_demo_writes_figures_and_metrics(tmp_path):
    demo = _load()
    assert demo.main(["--quick", "--no-progress", "--out", str(tmp_path)]) == 0
    m = json.loads((tmp_path / "whisker_ratslam_metrics.json").read_text())
    assert KEYS <= set(m)
    assert (tmp_path / "whisker_ratslam_map.png").stat().st_size > 10_000
    assert (tmp_path / "whisker_ratslam_experiences.png").stat().st_size > 5_000
    # the chain really ran: most whisks touched the mug, one experience per new region at least
    assert m["observations"] >= 0.8 * m["whisks"] and m["experiences"] >= m["regions"] > 0
    # without re-localisation the object map is dead reckoning: its error is of the same size
    assert m["map_median_position_error_m"] < 2.5 * m["dr_median_position_error_m"] + 0.02
    assert 0.03 < m["step_translation_m"] < 0.12 and 3.0 < m["step_rotation_deg"] < 13.0


@pytest.mark.xfail(strict=True, reason=(
    "issue 11 acceptance not met yet: on the Mug (2 loops, thesis contact noise) re-localisations go to the wrong "
    "place (median 0.41 m / 98 deg vs dead reckoning 0.13 m / 25 deg, step 6.5 cm / 11.7 deg): the PFH is "
    "rotation invariant and the Mug symmetric, and the 5-cell axes alias places; see the issue note"))
@pytest.mark.slow
def test_second_loop_relocalises_below_half_dead_reckoning_and_the_step_on_the_mug(tmp_path):
    demo = _load()
    m = demo.run("mug", loops=2, progress=False)["metrics"]
    assert m["relocalisations_second_loop"] > 0
    assert m["median_position_error_m"] <= 0.5 * m["dr_median_position_error_m"]
    assert m["median_position_error_m"] < m["step_translation_m"] and not math.isnan(m["median_position_error_m"])
