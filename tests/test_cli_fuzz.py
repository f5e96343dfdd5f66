"""Every ``cansim`` subcommand with malformed arguments, run as a subprocess (issue 25).

Each call must exit non-zero (not 1, the code of an internal error) with one line saying
what is wrong - argparse's usage lines aside -, never a traceback, and within a bound
(``subprocess.run``'s timeout: a call that starts real work on bad input fails here).
The arguments are drawn by hypothesis: bad numbers, unknown options, unknown names,
missing files, and spec / bag / config files of random or wrong content. Few examples
in the fast loop (``CANSIM_CLI_FUZZ_EXAMPLES=N`` for more); the studies, whose imports
take seconds, and the longer draw are marked slow.
"""

from __future__ import annotations

import os
import string
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

ROOT = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent
N = int(os.environ.get("CANSIM_CLI_FUZZ_EXAMPLES", "3"))
SETTINGS = dict(max_examples=N, deadline=None, suppress_health_check=[HealthCheck.too_slow])
#: a malformed call must fail within this (imports included; the studies import scikit-learn, numba, trimesh)
BOUND_S = 60.0


class File:
    """A file written into the call's working folder first; the call names ``arg`` (default: the file)."""

    def __init__(self, name: str, content: bytes | None, arg: str | None = None) -> None:
        self.name, self.content = name, content  # content None: the file does not exist
        self.arg = name if arg is None else arg

    def __repr__(self) -> str:
        return f"File({self.name!r}, {self.content[:40] if self.content else self.content!r})"


def run_cli(argv: list, timeout: float = BOUND_S) -> subprocess.CompletedProcess:
    """``python -m cansim *argv`` in a fresh folder (``File`` items written there first)."""
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), str(TESTS), os.environ.get("PYTHONPATH", "")])))
    with tempfile.TemporaryDirectory() as tmp:
        args = []
        for a in argv:
            if isinstance(a, File):
                if a.content is not None:
                    (Path(tmp) / a.name).parent.mkdir(parents=True, exist_ok=True)
                    (Path(tmp) / a.name).write_bytes(a.content)
                args.append(a.arg)
            else:
                args.append(a)
        try:
            return subprocess.run([sys.executable, "-m", "cansim", *args], cwd=tmp, env=env, capture_output=True,
                                  text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"cansim {' '.join(args)} ran past {timeout:.0f} s on malformed arguments (no bound)")


def message_lines(stderr: str) -> list[str]:
    """stderr without argparse's usage block, progress bars and warnings."""
    out, in_usage = [], False
    for line in stderr.splitlines():
        if line.startswith("usage:"):
            in_usage = True
            continue
        if in_usage and line.startswith(" "):
            continue
        in_usage = False
        if line.strip() and ": warning: " not in line and "it/s]" not in line and "%|" not in line:
            out.append(line)
    return out


def assert_clean_refusal(argv: list, proc: subprocess.CompletedProcess) -> str:
    shown = " ".join(map(str, argv))
    assert "Traceback" not in proc.stderr, f"cansim {shown}: traceback\n{proc.stderr[-3000:]}"
    assert proc.returncode not in (0, 1), f"cansim {shown}: exit {proc.returncode}\n{proc.stderr[-2000:]}"
    lines = message_lines(proc.stderr)
    assert len(lines) == 1, f"cansim {shown}: expected one line, got {lines}"
    return lines[0]


# ------------------------------------------------------------ bad values
names = st.text(string.ascii_lowercase + string.digits + "_", min_size=1, max_size=8)
#: an option no parser has, nor a prefix of one (argparse accepts unambiguous prefixes)
unknown_option = names.map(lambda s: f"--zz-{s}")
not_an_int = st.one_of(names.filter(lambda s: not s.isdigit()), st.sampled_from(["1.5", "1e3", "", "0x10", "nan"]))
negative = st.integers(max_value=-1).map(str)
not_positive = st.integers(max_value=0).map(str)
bad_float = st.one_of(st.sampled_from(["nan", "inf", "-inf", "-1", "abc", ""]), st.floats(max_value=-1e-9).map(repr))
junk = st.one_of(st.binary(max_size=300), st.text(max_size=200).map(str.encode))


def _spec_text(body: dict) -> bytes:
    return "\n".join(f"{k} = {v}" for k, v in body.items()).encode()


#: ROS2 bag folders whose metadata.yaml is junk, or YAML of the right layout with wrong types
_ROS2_META = """rosbag2_bagfile_information:
  version: 5
  storage_identifier: sqlite3
  relative_file_paths: [{files}]
  topics_with_message_count:
    - topic_metadata: {{name: {topic}, type: {msgtype}, serialization_format: cdr}}
      message_count: {count}
"""
bad_ros2_meta = st.one_of(
    junk,
    st.fixed_dictionaries({"files": st.sampled_from(["x.db3", "", "5", "[1, 2]"]),
                           "topic": st.sampled_from(["5", "/odom", "[a]", "null", "{a: 1}"]),
                           "msgtype": st.sampled_from(["nav_msgs/msg/Odometry", "7", "null", "zz/msg/Nope"]),
                           "count": st.sampled_from(["1", "-1", "x", "1e400"])}).map(lambda d: _ROS2_META.format(**d).encode()),
)

#: sweep specs that are valid TOML but malformed (always at least one bad entry)
bad_specs = st.one_of(
    st.fixed_dictionaries({"experiment": st.sampled_from(['"bump"', '"sweep_fixtures:fast"']),
                           "metrics": st.sampled_from(['["fwhm_cells"]', '"value"', "[]", "[1]"]),
                           "n_seeds": st.one_of(st.integers(max_value=0), st.just(2**63 - 1), st.just(1.5)).map(str)}),
    st.fixed_dictionaries({"experiment": st.one_of(names.map(lambda s: f'"zz_{s}"'), st.just("5"), st.just('"no.module:fn"')),
                           "metrics": st.just('["x"]')}),
    st.fixed_dictionaries({"experiment": st.just('"bump"'), "metrics": st.just('["fwhm_cells"]'),
                           "grid": st.sampled_from(["{ n_cells = [-5] }", "{ global_inhibition = [-1.0] }",
                                                    "{ duration_steps = [0] }", "{ n_cells = 3 }", "{ zz_unknown = [1] }",
                                                    '{ n_cells = ["many"] }', "{ n_cells = [] }"])}),
).map(_spec_text)

commands = {
    "demo": st.one_of(
        st.tuples(st.just("--seed"), st.one_of(not_an_int, negative)).map(list),
        st.tuples(st.sampled_from(["ratslam", "whisker"]), unknown_option).map(list),
        st.tuples(st.just("whisker"), st.just("--quick"), st.sampled_from(["--contact-noise", "--noise-scale"]), bad_float).map(list),
        st.tuples(st.just("whisker"), st.just("--contact-noise"), st.just("0.1"), st.just("--noise-scale"), st.just("0.3")).map(list),
        st.tuples(st.just("whisker"), st.just("--quick"), st.just("--object"), names.map(lambda s: f"zz_{s}")).map(list),
    ),
    "sweep": st.one_of(
        st.just([]),
        st.tuples(names.map(lambda s: File(f"{s}.toml", None))).map(list),
        st.tuples(junk.map(lambda b: File("spec.toml", b))).map(list),
        st.tuples(bad_specs.map(lambda b: File("spec.toml", b)), st.just("--no-progress")).map(list),
        st.tuples(st.just("spec.toml"), st.just("--workers"), st.one_of(not_positive, not_an_int)).map(list),
        st.tuples(st.just("spec.toml"), unknown_option).map(list),
    ),
    "replay": st.one_of(
        st.just([]),
        st.tuples(names.map(lambda s: File(f"{s}.bag", None))).map(list),
        st.tuples(junk.map(lambda b: File("run.bag", b)), st.just("--no-progress")).map(list),
        st.tuples(st.just("run.bag"), st.just("--stamps"), names.filter(lambda s: s not in ("header", "log"))).map(list),
        st.tuples(bad_ros2_meta.map(lambda b: File("ros2bag/metadata.yaml", b, arg="ros2bag")), st.just("--no-progress")).map(list),
        st.tuples(junk.map(lambda b: File("run.bag", b)), st.just("--config"),
                  junk.map(lambda b: File("config.txt", b)), st.just("--no-progress")).map(list),
    ),
    "backends": st.one_of(st.tuples(unknown_option).map(list), st.tuples(names).map(list)),
    "bench": st.one_of(
        st.tuples(st.just("--quick"), st.sampled_from(["--backends", "--workloads"]), names.map(lambda s: f"zz{s}")).map(list),
        st.tuples(st.just("--max-threads"), st.one_of(not_positive, not_an_int)).map(list),
        st.tuples(unknown_option).map(list),
    ),
    "study": st.one_of(
        st.tuples(names.map(lambda s: f"ch{s}")).map(list),
        st.tuples(st.just("ch5"), st.just("--quick"), st.sampled_from(["--loops", "--id-loops"]), not_positive).map(list),
        st.tuples(st.just("ch5"), st.just("--quick"), st.sampled_from(["--seed", "--workers"]), negative).map(list),
        st.tuples(st.just("recognition"), st.just("--quick"), st.sampled_from(["--seeds", "--whisks"]), not_positive).map(list),
        st.tuples(st.just("recognition"), st.just("--quick"), st.just("--seed"), negative).map(list),
        st.tuples(st.just("recognition"), st.just("--quick"), st.just("--matchers"), st.just("surface"),
                  st.just("--matcher"), st.just("thesis")).map(list),  # one option by two names: given twice
        st.tuples(st.just("recognition"), st.just("--quick"), st.just("--reach-contacts"),
                  st.one_of(negative, st.integers(65, 10**6).map(str), not_an_int)).map(list),
        st.tuples(st.just("recognition"), st.just("--quick"), st.just("--roll-deg"),
                  st.one_of(st.integers(361, 10**6).map(str), st.integers(-10**6, -361).map(str),
                            st.sampled_from(["nan", "inf", "-inf", "ninety", ""]))).map(list),
    ),
    "top": st.one_of(st.just([]), st.tuples(names.map(lambda s: f"zz{s}")).map(list), st.tuples(unknown_option).map(list)),
}


@pytest.mark.parametrize("command", sorted(commands))
@settings(**SETTINGS)
@given(data=st.data())
def test_malformed_arguments_are_refused_in_one_line(command, data):
    argv = data.draw(commands[command], label="argv")
    full = argv if command == "top" else [command, *argv]
    assert_clean_refusal(full, run_cli(full))


# ------------------------------------------------ the studies (slow imports)
studies = st.one_of(
    st.tuples(names.map(lambda s: f"ch{s}")).map(list),
    st.tuples(st.sampled_from(["ch3", "ch4", "ch5", "ch6", "recognition"]), st.just("--quick"), unknown_option).map(list),
    st.tuples(st.just("ch3"), st.just("--quick"), st.just("--repetitions"), st.one_of(not_positive, not_an_int)).map(list),
    st.tuples(st.just("ch5"), st.just("--quick"), st.sampled_from(["--loops", "--id-loops"]), not_positive).map(list),
    st.tuples(st.just("ch5"), st.just("--quick"), st.sampled_from(["--seed", "--workers", "--id-whisks"]), negative).map(list),
    st.tuples(st.just("ch5"), st.just("--quick"),
              st.sampled_from(["--noise-scale", "--pfh-threshold", "--sda-threshold", "--calibration-quantile"]),
              bad_float).map(list),
    st.tuples(st.just("ch5"), st.just("--quick"), st.just("--objects"), names.map(lambda s: f"zz_{s}")).map(list),
    st.tuples(st.just("ch6"), st.just("--quick"), st.sampled_from(["--seeds", "--iterations"]), not_positive).map(list),
    st.tuples(st.just("ch6"), st.just("--quick"), st.sampled_from(["--seed"]), negative).map(list),
    st.tuples(st.just("ch6"), st.just("--quick"), st.sampled_from(["--noise-scale", "--object-offset-m", "--believed-scale", "--odometry-noise"]),
              bad_float).map(list),
    st.tuples(st.just("recognition"), st.just("--quick"), st.sampled_from(["--seeds", "--whisks", "--map-loops", "--workers"]),
              not_positive).map(list),
    # the mesh options: a bad value, or an option with no mesh file to apply it to (registered objects only)
    st.tuples(st.sampled_from(["ch5", "ch6", "recognition"]), st.just("--quick"), st.just("--scale-to-m"),
              st.one_of(bad_float, st.sampled_from(["0", "5", "1e-9"]))).map(list),
    st.tuples(st.sampled_from(["ch5", "ch6", "recognition"]), st.just("--quick"), st.just("--up-axis"),
              st.one_of(names, st.sampled_from(["y", "-z", "yz", ""]))).map(list),
)


@pytest.mark.slow
@settings(**{**SETTINGS, "max_examples": max(N, 12)})
@given(argv=studies)
@example(argv=["ch5", "--quick", "--loops", "0"])  # ran the default 2 loops (0 is falsy): minutes of mapping
@example(argv=["ch5", "--quick", "--seed", "-1"])  # mapped for minutes before numpy refused the seed
@example(argv=["ch4", "--quick", "--seed", "-3"])  # a traceback (numpy's ValueError), exit 1
@example(argv=["ch6", "--quick", "--seed", "-1"])  # refused only after 35 s of work
def test_a_study_refuses_malformed_options_before_any_work(argv):
    full = ["study", *argv]
    assert_clean_refusal(full, run_cli(full))


# ----------------------------------------------- explicit regression examples
@pytest.mark.parametrize("argv", [["demo", "--seed", "-1", "ratslam"], ["demo", "ratslam", "--seed", "-1"],
                                  ["study", "ch5", "--quick", "--loops", "0"], ["study", "ch5", "--quick", "--seed", "-1"],
                                  ["study", "ch5", "--quick", "--calibration-quantile", "nan"]])
def test_negative_seeds_and_zero_loops_are_refused_up_front(argv):
    """``cansim demo --seed -1 ratslam`` printed numpy's traceback (exit 1); ``study ch5 --loops 0`` ran
    the default 2 loops and ``--seed -1`` mapped for minutes before failing (issue 25)."""
    proc = run_cli(argv, timeout=30.0)
    line = assert_clean_refusal(argv, proc)
    assert proc.returncode == 2 and argv[-2].lstrip("-") in line.replace("_", "-")
