"""An option that stores one value may be given once (:mod:`whisker_io.command_line`), in every demo, study and example."""

from __future__ import annotations

import argparse
import importlib
import inspect

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from whisker_io.command_line import CommandParser
from cansim.tools import cli


def _parser() -> CommandParser:
    ap = CommandParser(prog="tool")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--objects", nargs="+", default=["mug"])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--tag", action="append", default=[])
    ap.add_argument("-v", action="count", default=0)
    return ap


def test_one_value_each_is_kept_and_the_defaults_stand():
    args = _parser().parse_args(["--seed", "3", "--objects", "box", "mug"])
    assert (args.seed, args.objects, args.quick, args.tag, args.v) == (3, ["box", "mug"], False, [], 0)
    assert _parser().parse_args([]).seed == 0


@pytest.mark.parametrize("argv,first,then", [
    (["--seed", "3", "--seed", "5"], "3", "5"),
    (["--seed=3", "--quick", "--seed", "3"], "3", "3"),  # the same value twice is still twice
    (["--objects", "a", "b", "--objects", "c"], "a b", "c"),
])
def test_an_option_given_twice_is_a_usage_error_naming_it(capsys, argv, first, then):
    with pytest.raises(SystemExit) as exc:
        _parser().parse_args(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    name = "--objects" if "objects" in argv[0] else "--seed"
    assert f"argument {name}: given twice ({first}, then {then}); give it once" in err


def test_flags_counters_and_appends_repeat_as_argparse_defines():
    args = _parser().parse_args(["--quick", "--quick", "-v", "-v", "--tag", "a", "--tag", "b"])
    assert (args.quick, args.v, args.tag) == (True, 2, ["a", "b"])


def test_one_parser_parses_many_command_lines():
    ap = _parser()
    assert [ap.parse_args(["--seed", str(s)]).seed for s in range(4)] == [0, 1, 2, 3]
    assert ap.parse_known_args(["--seed", "7", "--other"]) == (argparse.Namespace(
        seed=7, objects=["mug"], quick=False, tag=[], v=0), ["--other"])


def test_sub_commands_refuse_repeats_too(capsys):
    ap = CommandParser(prog="top")
    sub = ap.add_subparsers(dest="command")
    sub.add_parser("run").add_argument("--seed", type=int)
    assert ap.parse_args(["run", "--seed", "1"]).seed == 1
    with pytest.raises(SystemExit):
        ap.parse_args(["run", "--seed", "1", "--seed", "2"])
    assert "given twice" in capsys.readouterr().err


@settings(max_examples=60, deadline=None)
@given(values=st.lists(st.integers(0, 99), min_size=1, max_size=4), quick=st.booleans())
def test_a_seed_given_n_times_parses_only_once(values, quick):
    argv = [tok for v in values for tok in ("--seed", str(v))] + (["--quick"] if quick else [])
    ap = _parser()
    if len(values) == 1:
        assert ap.parse_args(argv).seed == values[0]
    else:
        with pytest.raises(SystemExit):
            ap.parse_args(argv)
    assert ap.parse_args([]).seed == 0  # a refused command line leaves the parser as it was


def test_an_abbreviated_option_is_not_taken(capsys):
    """``--se`` was ``--seed`` by argparse's abbreviation: an option added later changes what it means (the
    recognition study's ``--seed 3`` was ``--seeds 3`` until it had a ``--seed``)."""
    ap = _parser()
    assert ap.parse_known_args(["--se", "1"])[1] == ["--se", "1"]  # left unknown
    with pytest.raises(SystemExit):
        ap.parse_args(["--se", "1"])
    assert "unrecognized arguments: --se 1" in capsys.readouterr().err


def test_a_namespace_given_to_two_parses_is_not_a_repeat():
    """Two parses into one namespace (a two-stage parse) stored each value once: not 'given twice'."""
    import argparse

    ns = argparse.Namespace()
    first = CommandParser(prog="a")
    first.add_argument("--config")
    second = CommandParser(prog="b")
    second.add_argument("--config")
    second.add_argument("--seed", type=int)
    first.parse_known_args(["--config", "x.toml", "--seed", "2"], namespace=ns)
    second.parse_args(["--config", "x.toml", "--seed", "2"], namespace=ns)
    assert (ns.config, ns.seed) == ("x.toml", 2)


MODULES = ("whisker_io.radial.__main__", "cansim.studies.ch3_maze", "cansim.studies.ch4_radial_distance", "cansim.studies.ch5_object_maps",
           "cansim.studies.ch6_active_exploration", "cansim.studies.rat_trajectories", "cansim.studies.ratslam_demo",
           "cansim.studies.recognition", "cansim.studies.whisker_ratslam_demo")


@pytest.mark.parametrize("module", MODULES)
def test_every_study_and_demo_parses_with_it(module):
    assert "CommandParser(" in inspect.getsource(importlib.import_module(module).main)
    assert set(cli.STUDIES.values()) | set(cli.DEMOS.values()) <= set(MODULES)


def test_no_command_line_here_parses_with_plain_argparse():
    """Every parser of the package and its examples is a CommandParser (the bench scripts are tools, not commands)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    plain = [str(p.relative_to(root)) for folder in ("cansim", "maps", "whisker_io", "examples")
             for p in (root / folder).rglob("*.py") if "argparse.ArgumentParser(" in p.read_text(encoding="utf-8")]
    assert plain == []


#: Each command line also holds something that stops the run at once (an unwritable --out, a value out of range)
#: should the repeat go through: the test fails fast instead of running a study.
@pytest.mark.parametrize("argv,option", [
    (["demo", "--seed", "3", "whisker", "--seed", "5", "--out", "{blocked}"], "--seed"),  # argparse kept 5, silently
    (["study", "ch4", "--out", "a", "--out={blocked}"], "--out"),
    (["study", "ch4", "--seed", "-1", "--seed", "-2"], "--seed"),  # the study's own option
    (["study", "ch6", "--objects", "box", "mug", "--objects", "mug", "box", "--iterations", "0"], "--objects"),
])
def test_the_command_refuses_an_option_given_twice_before_any_work(tmp_path, capsys, monkeypatch, argv, option):
    (tmp_path / "file").write_text("")
    monkeypatch.chdir(tmp_path)
    argv = [a.replace("{blocked}", str(tmp_path / "file" / "out")) for a in argv]
    try:  # the command's own options fail in its parser, a study's in the study's (its main returns the code)
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    assert f"argument {option}: given twice" in capsys.readouterr().err
    assert [p.name for p in tmp_path.iterdir()] == ["file"]  # nothing written


# ------------------------------------------------ one option name across the commands (a user's pass, session 46)
class _Stop(Exception):
    pass


def test_the_demo_takes_the_studies_noise_scale(monkeypatch, tmp_path):
    """``--noise-scale S`` (the Ch.5 / Ch.6 studies' option) is ``--contact-noise 0.25 S``: Sec 6.1.3.1.2's
    contact-position noise is 25 % of the whisker length."""
    import cansim.studies.whisker_ratslam_demo as demo

    seen = []

    def fake_run(*args, **kwargs):
        seen.append(kwargs["contact_noise"])
        raise _Stop

    monkeypatch.setattr(demo, "run", fake_run)
    for argv, expected in ((["--noise-scale", "0.3"], 0.075), (["--noise-scale", "1"], 0.25), (["--contact-noise", "0.1"], 0.1),
                           ([], 0.075), (["--noise-scale", "0"], 0.0)):
        with pytest.raises(_Stop):
            demo.main(["--out", str(tmp_path), "--quick", *argv])
        assert seen[-1] == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("argv,says", [
    (["--contact-noise", "0.1", "--noise-scale", "0.3"], "not allowed with argument"),  # one noise, two ways
    (["--noise-scale", "5"], "--noise-scale must lie in [0, 4]"),
    (["--noise-scale", "nan"], "--noise-scale must lie in [0, 4]"),
])
def test_the_demo_refuses_a_second_or_a_bad_noise(tmp_path, capsys, argv, says):
    import cansim.studies.whisker_ratslam_demo as demo

    with pytest.raises(SystemExit) as exc:
        demo.main(["--out", str(tmp_path), "--quick", *argv])
    assert exc.value.code == 2 and says in capsys.readouterr().err


def test_recognition_takes_a_first_seed_and_the_matcher_by_either_name(monkeypatch, tmp_path, capsys):
    from cansim.studies import recognition

    seen = []

    def fake_run(*args, **kwargs):
        seen.append(kwargs)
        raise _Stop

    monkeypatch.setattr(recognition, "run", fake_run)
    with pytest.raises(_Stop):
        recognition.main(["--quick", "--out", str(tmp_path), "--seed", "3", "--seeds", "3", "--matcher", "surface"])
    assert list(seen[-1]["seeds"]) == [3, 4, 5] and seen[-1]["matchers"] == ["surface"]
    with pytest.raises(_Stop):
        recognition.main(["--out", str(tmp_path)])
    assert list(seen[-1]["seeds"]) == [0, 1, 2]  # the default, as before
    for argv, says in ((["--matchers", "thesis", "--matcher", "surface"], "given twice"),  # two names of one option
                       (["--seed", "-1"], "--seed must be >= 0")):
        with pytest.raises(SystemExit) as exc:
            recognition.main(["--quick", "--out", str(tmp_path), *argv])
        assert exc.value.code == 2 and says in capsys.readouterr().err


def test_ch5_takes_map_loops_as_recognition_does(capsys, tmp_path):
    from cansim.studies import ch5_object_maps as ch5

    for argv, says in ((["--loops", "2", "--map-loops", "3"], "argument --loops/--map-loops: given twice"),
                       (["--map-loops", "0"], "--loops (--map-loops) must be >= 1, got 0")):
        with pytest.raises(SystemExit) as exc:
            ch5.main(["--quick", "--out", str(tmp_path), *argv])
        assert exc.value.code == 2 and says in capsys.readouterr().err


# ------------------------------------------------------------------ how a script ends on an error (run_command)
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

from whisker_io import errors as werr  # noqa: E402
from whisker_io.command_line import (EXIT_BAD_INPUT, EXIT_FAILED, EXIT_INTERNAL, EXIT_MISSING_EXTRA,  # noqa: E402
                                     error_status, run_command)

# the statuses README's table of `cansim` exit codes gives, by hand: 3 bad input, 4 failure, 6 missing extra, 1 a bug
_BY_HAND = [
    (werr.InvalidInputError("no mesh file at x.obj"), 3),
    (werr.CorruptFileError("not a readable GLB mesh"), 3),
    (werr.ConfigError("seed must be >= 0"), 3),
    (FileNotFoundError(2, "No such file", "x.csv"), 3),
    (werr.MissingExtraError("nir needs cansim[spiking]"), 6),
    (ImportError("install it: pip install 'cansim[sweep]'"), 6),
    (__import__("cansim.errors").errors.BackendUnavailableError("--backend opencl: no OpenCL device"), 6),
    (werr.CansimError("the run could not finish"), 4),
    (PermissionError(13, "Permission denied", "/out"), 4),
    (RuntimeError("worker died"), 4),
    (ValueError("invalid literal"), 1),
    (KeyError("x"), 1),
]


@pytest.mark.parametrize("exc,status", _BY_HAND, ids=[f"{type(e).__name__}-{s}" for e, s in _BY_HAND])
def test_error_status_gives_the_statuses_of_the_exit_code_table(exc, status):
    assert error_status(exc)[0] == status
    assert (EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_FAILED, EXIT_MISSING_EXTRA) == (1, 3, 4, 6)
    assert cli._classify(exc)[0] == status  # `cansim` and the scripts classify alike


@pytest.mark.parametrize("exc,status", [x for x in _BY_HAND if x[1] != 1])
def test_a_script_ends_on_a_known_error_with_one_line_and_its_status(capsys, exc, status):
    def main() -> int:
        raise exc

    assert run_command(main, "prog") == status
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("prog: ")
    assert ("error:" in err) == (status != EXIT_MISSING_EXTRA)


@pytest.mark.parametrize("exc", [x[0] for x in _BY_HAND if x[1] == 1])
def test_a_script_ends_on_an_unknown_error_with_its_traceback(exc):
    def main() -> int:
        raise exc

    with pytest.raises(type(exc)):
        run_command(main, "prog")


@given(st.text(min_size=0, max_size=60), st.sampled_from([werr.InvalidInputError, werr.CorruptFileError, werr.ConfigError,
                                                          werr.CansimError, werr.MissingExtraError, RuntimeError]))
@settings(max_examples=60, deadline=None)
def test_any_message_of_a_known_error_ends_in_one_line(message, kind):
    import contextlib
    import io

    from whisker_io.command_line import report_error

    code, line = error_status(kind(message))
    assert code in (EXIT_BAD_INPUT, EXIT_FAILED, EXIT_MISSING_EXTRA) and "\n" not in line and "\r" not in line
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert report_error(kind(message), "prog") == code
    said = err.getvalue()
    assert said.count("\n") == 1 and said.endswith("\n") and "\r" not in said and said.startswith("prog: ")


@pytest.mark.parametrize("module", ["cansim.studies.whisker_ratslam_demo", "cansim.studies.ch5_object_maps",
                                    "cansim.studies.ch6_active_exploration", "cansim.studies.recognition"])
def test_a_study_run_as_a_module_refuses_a_missing_mesh_file_in_one_line(tmp_path, module):
    option = "--object" if module.endswith("demo") else "--objects"
    objects = ["nope.obj"] if option == "--object" else ["nope.obj", "mug"]
    proc = subprocess.run([sys.executable, "-m", module, "--quick", "--no-progress", "--out", str(tmp_path / "out"),
                           option, *objects], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert proc.returncode == EXIT_BAD_INPUT, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and "no mesh file at nope.obj" in proc.stderr
    assert [ln for ln in proc.stderr.splitlines() if "error:" in ln] == [proc.stderr.strip().splitlines()[-1]]
    assert not Path(tmp_path / "out").exists() or not any((tmp_path / "out").rglob("*.csv"))


@pytest.mark.parametrize("module", ["cansim.studies.ch5_object_maps", "cansim.studies.ch6_active_exploration",
                                    "cansim.studies.recognition"])
def test_a_novel_flag_with_no_object_means_none(module):
    """``--novel`` with nothing after it: no novel object, in every study that takes novel objects."""
    parser = _study_parser(module)
    assert parser.parse_args(["--novel"]).novel == []
    assert parser.parse_args(["--novel", "a.obj", "knot"]).novel == ["a.obj", "knot"]


def _study_parser(module: str) -> argparse.ArgumentParser:
    """The study's own parser, caught as its main builds it (main stops at parse_args)."""
    caught = {}
    real = CommandParser.parse_args

    def catch(self, *a, **k):
        caught["parser"] = self
        raise SystemExit(0)

    mod = importlib.import_module(module)
    CommandParser.parse_args = catch
    try:
        with pytest.raises(SystemExit):
            mod.main(["--quick"])
    finally:
        CommandParser.parse_args = real
    return caught["parser"]


def test_a_script_stopped_by_ctrl_c_ends_as_cansim_does(capsys, monkeypatch):
    from whisker_io.command_line import EXIT_INTERRUPTED

    def main() -> int:
        raise KeyboardInterrupt

    assert run_command(main, "prog") == EXIT_INTERRUPTED == cli.EXIT_INTERRUPTED
    assert capsys.readouterr().err == "prog: interrupted\n"

    def fails() -> int:
        raise RuntimeError("worker died")

    monkeypatch.setenv("CANSIM_DEBUG", "1")  # a failure's traceback, when asked for
    with pytest.raises(RuntimeError):
        run_command(fails, "prog")
