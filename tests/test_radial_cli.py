"""`python -m whisker_io.radial train|evaluate`: one command trains all models, one evaluates them."""

from __future__ import annotations

import csv

import pytest

from whisker_io.radial.__main__ import main

pytestmark = pytest.mark.filterwarnings("ignore::sklearn.exceptions.ConvergenceWarning")


@pytest.mark.slow  # trains every Table 4.1 model (fast loop <= 4 min)
def test_train_then_evaluate_writes_one_row_per_model(tmp_path, capsys):
    models = tmp_path / "models"
    assert main(["train", "--models", str(models), "--quick"]) == 0
    err = capsys.readouterr().err
    assert "ConvergenceWarning" not in err  # summarised in one note line, not one line per fit
    assert sum("stopped at the iteration bound" in line for line in err.splitlines()) <= 1
    names = sorted(p.stem for p in models.glob("*.skops"))
    assert {"svr9", "svr10", "poly5", "nn1", "tip", "random"} <= set(names) and len(names) == 14
    assert main(["evaluate", "--models", str(models), "--out", str(tmp_path), "--quick"]) == 0
    with open(tmp_path / "radial_results.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(r["model"] for r in rows) == names
    tip = next(r for r in rows if r["model"] == "tip")
    svr = next(r for r in rows if r["model"] == "svr9")
    assert float(svr["median_abs_error"]) < float(tip["median_abs_error"])


def test_evaluate_without_models_or_with_a_corrupt_file_fails_cleanly(tmp_path, capsys):
    assert main(["evaluate", "--models", str(tmp_path)]) == 2
    assert "run 'python -m whisker_io.radial train' first" in capsys.readouterr().err
    (tmp_path / "svr9.skops").write_bytes(b"not a model")
    assert main(["evaluate", "--models", str(tmp_path), "--quick"]) == 3  # bad input (a corrupt file), as cansim's table
    err = capsys.readouterr().err
    assert err.startswith("python -m whisker_io.radial: error: ") and err.count("\n") == 1


def test_exit_status_2_for_usage_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:
        main(["fly"])
    assert info.value.code == 2
    assert main(["evaluate", "--models", str(tmp_path / "missing")]) == 2
    afile = tmp_path / "file"
    afile.write_text("")
    assert main(["train", "--models", str(afile), "--quick"]) == 2
    assert "not a folder" in capsys.readouterr().err
