"""Parameter sweeps of experiments on Dask: a TOML spec in, a tidy Parquet table out.

An *experiment* is a plain function ``run(params: dict, seed: int) -> dict`` that
returns flat metrics (``float``, ``int``, ``str`` or ``bool``) for one parameter set
and is deterministic for a seed; a spec names it by a dotted path
``"package.module:function"`` (or by a bare name ``NAME``, short for
``"cansim.experiments.NAME:run"``).

Sweep spec (TOML; keys)
-----------------------
``experiment``
    The experiment (required).
``[grid]``
    ``parameter = [values, ...]``; the cells are the Cartesian product.
``[random]``
    ``n_samples = N`` and ``parameter = {distribution = ..., ...}`` with
    ``"uniform"`` (``low``, ``high``), ``"loguniform"`` (``low``, ``high`` > 0),
    ``"normal"`` (``mean``, ``std``) or ``"choice"`` (``values``). The N samples are
    crossed with the grid cells. Each parameter has its own random stream, derived
    from ``base_seed`` and its name, so adding a parameter leaves the others' samples
    unchanged.
``[fixed]``
    ``parameter = value`` passed unchanged to every cell (optional).
``seeds = [s, ...]`` or ``n_seeds = N``
    Literal seeds run for every cell, or N seeds per cell derived from ``base_seed``
    and the cell's parameters (SHA-256 of their canonical JSON), so that each cell is
    reproducible alone, whatever else the sweep holds. Default: ``n_seeds = 1``.
``base_seed``
    Integer >= 0 (default 0).
``metrics = ["name", ...]``
    Keys of the experiment's result to record (required); a missing key is an
    error of that cell.
``scheduler = "tcp://HOST:PORT"``
    Run on an existing Dask cluster (optional; the command line's ``--scheduler`` wins).
``name``, ``description``
    Free text (optional).

Any other key, or a malformed value, raises :class:`~cansim.errors.ConfigError`
naming the key.

Output
------
``OUT/results.parquet`` holds one row per cell x seed ("task"): the parameters, the
seed, the metrics, ``status`` (``"ok"`` or ``"error"``), ``error`` (the exception,
one line), ``wall_time_s``, ``task_id`` (a hash of experiment, parameters and seed),
``cell_id`` (a hash of the parameters), ``experiment``, ``hostname``, the versions
``cansim_version``, ``numpy_version``, ``python_version`` and ``finished_utc``.
Each finished task is written at once, durably, as ``OUT/parts/<task_id>.parquet``
(written to a temporary file, then renamed); at the end the parts are compacted into
``results.parquet``. A re-run reads both and skips tasks already recorded - after a
crash or Ctrl-C it resumes where it stopped; errored tasks are retried only with
``retry_errors=True``. ``OUT/spec.json`` remembers the experiment and metrics: a
re-run into the same folder must keep them (the grid may grow).

Execution
---------
Tasks are submitted to a ``dask.distributed`` client: the one passed in, one
connected to ``scheduler``, or by default a ``LocalCluster`` of worker *processes*
(one thread each) sized to the CPUs this process may use. The experiment must be
importable on the workers. A worker that dies mid-task is replaced and its task
re-run by Dask; a task whose worker died repeatedly is recorded as an error.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import contextlib
import hashlib
import importlib
import inspect
import itertools
import json
import logging
import math
import os
import platform
import re
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cansim.errors import CansimError, ConfigError, CorruptFileError, InvalidInputError, missing_extra
from whisker_io.persistence import write_atomically
from whisker_io.validation import config_field

__all__ = [
    "check_parameters",
    "SweepSpec",
    "RandomParam",
    "Task",
    "SweepResult",
    "load_spec",
    "parse_spec",
    "expand",
    "cell_seeds",
    "default_workers",
    "resolve_experiment",
    "run_task",
    "read_results",
    "run",
]

log = logging.getLogger(__name__)

Scalar = float | int | str | bool

#: columns every row has besides the parameters and metrics
RESERVED_COLUMNS = (
    "seed", "status", "error", "wall_time_s", "task_id", "cell_id", "experiment", "hostname",
    "cansim_version", "numpy_version", "python_version", "finished_utc",
)
#: Most tasks (cells x seeds) one sweep may have; a spec over it is a ConfigError before any work.
MAX_TASKS = 1_000_000
_TOP_KEYS = ("experiment", "grid", "random", "fixed", "seeds", "n_seeds", "base_seed", "metrics", "scheduler",
             "name", "description")
_DISTRIBUTIONS = {
    "uniform": ("low", "high"),
    "loguniform": ("low", "high"),
    "normal": ("mean", "std"),
    "choice": ("values",),
}
_EXPERIMENT = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*(:[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*)?$")
_ADDRESS = re.compile(r"^[a-z][a-z0-9+]*://([^\s/:\[\]]+|\[[0-9A-Fa-f:.]+\])(:\d{1,5})?/?$")
_SEED_LIMIT = 2**31  # derived seeds fit an int32 and every RNG constructor


# ------------------------------------------------------------------ spec
@dataclasses.dataclass(frozen=True)
class RandomParam:
    """One randomly sampled parameter of ``[random]``.

    Parameters
    ----------
    distribution : {"uniform", "loguniform", "normal", "choice"}
    args : dict
        ``low``/``high`` (uniform, loguniform), ``mean``/``std`` (normal) or
        ``values`` (choice, a tuple of scalars).
    """

    distribution: str
    args: Mapping[str, Any]


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """A validated sweep spec (see the module docstring for the TOML keys).

    Attributes
    ----------
    experiment : str
        ``"package.module:function"``.
    grid : dict
        ``parameter -> tuple of values``.
    random : dict
        ``parameter -> RandomParam``.
    n_samples : int
        Random samples crossed with the grid (1 when ``random`` is empty).
    fixed : dict
        ``parameter -> value`` for every cell.
    seeds : tuple of int or None
        Literal seeds, or None to derive ``n_seeds`` per cell.
    n_seeds : int
    base_seed : int
    metrics : tuple of str
    scheduler : str or None
    name : str
    description : str
    """

    experiment: str
    metrics: tuple[str, ...]
    grid: Mapping[str, tuple[Scalar, ...]] = dataclasses.field(default_factory=dict)
    random: Mapping[str, RandomParam] = dataclasses.field(default_factory=dict)
    n_samples: int = 1
    fixed: Mapping[str, Scalar] = dataclasses.field(default_factory=dict)
    seeds: tuple[int, ...] | None = None
    n_seeds: int = 1
    base_seed: int = 0
    scheduler: str | None = None
    name: str = "sweep"
    description: str = ""

    @property
    def parameters(self) -> tuple[str, ...]:
        """Every parameter name: grid, then random, then fixed."""
        return (*self.grid, *self.random, *self.fixed)

    @property
    def n_cells(self) -> int:
        """Number of parameter sets (grid cells x random samples)."""
        return math.prod(len(v) for v in self.grid.values()) * (self.n_samples if self.random else 1)

    @property
    def n_tasks(self) -> int:
        """Number of rows of a complete sweep (cells x seeds)."""
        return self.n_cells * (len(self.seeds) if self.seeds is not None else self.n_seeds)


def _is_scalar(value: Any) -> bool:
    if isinstance(value, bool) or isinstance(value, str):
        return True
    if isinstance(value, int):
        return True
    return isinstance(value, float) and math.isfinite(value)


def _check_scalar(key: str, value: Any) -> Scalar:
    if not _is_scalar(value):
        raise ConfigError(f"{key}: {value!r} is not a finite number, integer, string or boolean")
    return value


def _kind(value: Scalar) -> str:
    return "bool" if isinstance(value, bool) else "str" if isinstance(value, str) else "number"


def _one_kind(key: str, values: tuple[Scalar, ...]) -> tuple[Scalar, ...]:
    """A parameter's values share one kind (numbers, strings or booleans): a results column has one type."""
    kinds = {_kind(v) for v in values}
    if len(kinds) > 1:
        raise ConfigError(f"{key}: values mix {' and '.join(sorted(kinds))}s ({list(values)}); a column holds one type")
    return values


#: the message of a malformed number of the spec (config_field's template: key, allowed values, value given)
_EXPECTED = "{name}: expected {want}, got {value!r}"


def _int(key: str, value: Any, minimum: int) -> int:
    return int(config_field(value, key, int, minimum=minimum, message=_EXPECTED))


def _number(key: str, value: Any) -> float:
    # an integer too large for a float is refused here too (TOML integers have no size limit)
    return float(config_field(value, key, float, message=_EXPECTED))


def _table(key: str, value: Any) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{key}: expected a table (e.g. [{key}]), got {type(value).__name__}")
    for name in value:
        if not isinstance(name, str) or not name:
            raise ConfigError(f"{key}: parameter names must be non-empty strings, got {name!r}")
    return value


def _random_param(key: str, value: Any) -> RandomParam:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{key}: expected {{distribution = ..., ...}}, got {value!r}")
    dist = value.get("distribution")
    if dist not in _DISTRIBUTIONS:
        raise ConfigError(f"{key}.distribution: expected one of {sorted(_DISTRIBUTIONS)}, got {dist!r}")
    needed = _DISTRIBUTIONS[dist]
    extra = sorted(set(value) - {"distribution", *needed})
    if extra:
        raise ConfigError(f"{key}.{extra[0]}: not a parameter of the {dist} distribution (it takes {list(needed)})")
    missing = [k for k in needed if k not in value]
    if missing:
        raise ConfigError(f"{key}.{missing[0]}: missing; the {dist} distribution needs {list(needed)}")
    if dist == "choice":
        values = value["values"]
        if not isinstance(values, (list, tuple)) or not values:
            raise ConfigError(f"{key}.values: expected a non-empty list, got {values!r}")
        checked = tuple(_check_scalar(f"{key}.values", v) for v in values)
        return RandomParam(dist, {"values": _one_kind(f"{key}.values", checked)})
    a, b = (_number(f"{key}.{k}", value[k]) for k in needed)
    if dist in ("uniform", "loguniform") and not a < b:
        raise ConfigError(f"{key}.high: must be greater than low ({a!r}), got {b!r}")
    if dist == "loguniform" and a <= 0:
        raise ConfigError(f"{key}.low: must be > 0 for a loguniform distribution, got {a!r}")
    if dist == "normal" and not b > 0:
        raise ConfigError(f"{key}.std: must be > 0, got {b!r}")
    return RandomParam(dist, dict(zip(needed, (a, b))))


def parse_spec(data: Mapping[str, Any]) -> SweepSpec:
    """Validate a sweep spec given as a mapping (the parsed TOML).

    Parameters
    ----------
    data : mapping
        The keys of the module docstring.

    Returns
    -------
    SweepSpec

    Raises
    ------
    ConfigError
        An unknown key, a missing required key or a malformed value; the message
        names the key (``grid.sigma``, ``random.n_samples``, ...).
    """
    if isinstance(data, SweepSpec):
        return data
    if not isinstance(data, Mapping):
        raise ConfigError(f"a sweep spec must be a table of keys, got {type(data).__name__}")
    unknown = sorted(str(k) for k in data if k not in _TOP_KEYS)
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown sweep spec key (known: {', '.join(_TOP_KEYS)})")
    experiment = data.get("experiment")
    if not isinstance(experiment, str) or not _EXPERIMENT.match(experiment):
        raise ConfigError(f"experiment: expected 'package.module:function' or an experiment name, got {experiment!r}")
    if ":" not in experiment:
        experiment = f"cansim.experiments.{experiment}:run" if "." not in experiment else experiment + ":run"

    grid: dict[str, tuple[Scalar, ...]] = {}
    for name, values in _table("grid", data.get("grid", {})).items():
        if not isinstance(values, (list, tuple)) or not values:
            raise ConfigError(f"grid.{name}: expected a non-empty list of values, got {values!r}")
        checked = tuple(_check_scalar(f"grid.{name}", v) for v in values)
        if len(set(map(_canonical, checked))) != len(checked):
            raise ConfigError(f"grid.{name}: values must be distinct, got {list(values)}")
        grid[name] = _one_kind(f"grid.{name}", checked)

    random: dict[str, RandomParam] = {}
    n_samples = 1
    rand_tab = dict(_table("random", data.get("random", {})))
    if rand_tab:
        if "n_samples" not in rand_tab:
            raise ConfigError("random.n_samples: missing; say how many random samples to draw")
        n_samples = _int("random.n_samples", rand_tab.pop("n_samples"), 1)
        if not rand_tab:
            raise ConfigError("random: n_samples is given but no parameter to sample")
        for name, value in rand_tab.items():
            random[name] = _random_param(f"random.{name}", value)

    fixed = {name: _check_scalar(f"fixed.{name}", v) for name, v in _table("fixed", data.get("fixed", {})).items()}

    seen: dict[str, str] = {}
    for section, names in (("grid", grid), ("random", random), ("fixed", fixed)):
        for name in names:
            if name in seen:
                raise ConfigError(f"{section}.{name}: the parameter is also in [{seen[name]}]; give it once")
            if name in RESERVED_COLUMNS:
                raise ConfigError(f"{section}.{name}: {name!r} is a reserved column name of the results; rename it")
            seen[name] = section

    if "seeds" in data and "n_seeds" in data:
        raise ConfigError("seeds: give either seeds = [...] or n_seeds = N, not both")
    seeds: tuple[int, ...] | None = None
    n_seeds = 1
    if "seeds" in data:
        raw = data["seeds"]
        if not isinstance(raw, (list, tuple)) or not raw:
            raise ConfigError(f"seeds: expected a non-empty list of integers, got {raw!r}")
        seeds = tuple(_int("seeds", s, 0) for s in raw)
        if len(set(seeds)) != len(seeds):
            raise ConfigError(f"seeds: values must be distinct, got {list(raw)}")
    elif "n_seeds" in data:
        n_seeds = _int("n_seeds", data["n_seeds"], 1)
    base_seed = _int("base_seed", data.get("base_seed", 0), 0)

    if "metrics" not in data:
        raise ConfigError("metrics: missing; list the result keys to record, e.g. metrics = [\"gain\"]")
    metrics = data["metrics"]
    if not isinstance(metrics, (list, tuple)) or not metrics or not all(isinstance(m, str) and m for m in metrics):
        raise ConfigError(f"metrics: expected a non-empty list of names, got {metrics!r}")
    if len(set(metrics)) != len(metrics):
        raise ConfigError(f"metrics: names must be distinct, got {list(metrics)}")
    for m in metrics:
        if m in RESERVED_COLUMNS:
            raise ConfigError(f"metrics: {m!r} is a reserved column name of the results; rename it in the experiment")
        if m in seen:
            raise ConfigError(f"metrics: {m!r} is also a parameter ([{seen[m]}]); a column holds one of them")

    scheduler = data.get("scheduler")
    if scheduler is not None and (not isinstance(scheduler, str) or not _ADDRESS.match(scheduler)):
        raise ConfigError(f"scheduler: expected an address like 'tcp://HOST:PORT', got {scheduler!r}")
    for key in ("name", "description"):
        if key in data and not isinstance(data[key], str):
            raise ConfigError(f"{key}: expected a string, got {data[key]!r}")
    name = data.get("name", "sweep")
    if "name" in data and not re.match(r"^[\w.-]+$", name):
        raise ConfigError(f"name: use letters, digits, '_', '-' or '.', got {name!r}")
    n_tasks = math.prod(len(v) for v in grid.values()) * n_samples * (len(seeds) if seeds is not None else n_seeds)
    if n_tasks > MAX_TASKS:  # checked before anything is enumerated: a huge count fails at once
        raise ConfigError(f"the sweep has {n_tasks} tasks (grid cells x samples x seeds), more than the limit "
                          f"{MAX_TASKS}; lower n_seeds, random.n_samples or the grid")
    return SweepSpec(
        experiment=experiment, metrics=tuple(metrics), grid=grid, random=random, n_samples=n_samples, fixed=fixed,
        seeds=seeds, n_seeds=n_seeds, base_seed=base_seed, scheduler=scheduler, name=name,
        description=data.get("description", ""),
    )


def load_spec(path: str | os.PathLike[str]) -> SweepSpec:
    """Read and validate a TOML sweep spec file.

    The spec's ``name`` defaults to the file's stem.

    Raises
    ------
    ConfigError
        The file is missing or not valid TOML (line and column in the message), or a
        key is malformed.
    """
    try:
        import tomllib  # type: ignore[import-not-found]
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]

    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{p}: no such sweep spec file") from None
    except IsADirectoryError:
        raise ConfigError(f"{p}: is a folder, not a sweep spec file (.toml)") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{p}: not a UTF-8 text file ({exc.reason}); a sweep spec is TOML") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    data.setdefault("name", re.sub(r"[^\w.-]", "_", p.stem) or "sweep")
    try:
        return parse_spec(data)
    except ConfigError as exc:
        raise ConfigError(f"{p}: {exc}") from None


def _as_spec(spec: SweepSpec | Mapping[str, Any] | str | os.PathLike[str]) -> SweepSpec:
    if isinstance(spec, SweepSpec):
        return spec
    if isinstance(spec, Mapping):
        return parse_spec(spec)
    if isinstance(spec, (str, os.PathLike)):
        return load_spec(spec)
    raise ConfigError(f"spec must be a SweepSpec, a mapping or a path to a TOML file, got {type(spec).__name__}")


# ------------------------------------------------------------------ expansion
@dataclasses.dataclass(frozen=True)
class Task:
    """One row of a sweep: one parameter set and one seed.

    Attributes
    ----------
    experiment : str
    params : dict
        Parameter name -> value (grid, random and fixed).
    seed : int
    metrics : tuple of str
    task_id : str
        16 hex digits of SHA-256 over (experiment, parameters, seed).
    cell_id : str
        16 hex digits of SHA-256 over the parameters.
    """

    experiment: str
    params: Mapping[str, Scalar]
    seed: int
    metrics: tuple[str, ...]
    task_id: str
    cell_id: str


def _canonical(value: Any) -> str:
    return json.dumps(value, sort_keys=True, separators=(",", ":"), allow_nan=False)


def _digest(*parts: Any) -> int:
    return int.from_bytes(hashlib.sha256(_canonical(list(parts)).encode()).digest()[:8], "big")


def _draw(name: str, param: RandomParam, n: int, base_seed: int) -> list[Scalar]:
    rng = np.random.default_rng([base_seed, _digest("random", name) % _SEED_LIMIT])
    a = param.args
    if param.distribution == "uniform":
        vals: Iterable[Any] = rng.uniform(a["low"], a["high"], n)
    elif param.distribution == "loguniform":
        vals = np.exp(rng.uniform(math.log(a["low"]), math.log(a["high"]), n))
    elif param.distribution == "normal":
        vals = rng.normal(a["mean"], a["std"], n)
    else:
        choices = a["values"]
        return [choices[int(i)] for i in rng.integers(0, len(choices), n)]
    return [float(v) for v in vals]


def cell_seeds(spec: SweepSpec, params: Mapping[str, Scalar]) -> tuple[int, ...]:
    """The seeds of one cell: the literal ``seeds``, or ``n_seeds`` derived from ``base_seed`` and the parameters."""
    if spec.seeds is not None:
        return spec.seeds
    key = _canonical(dict(params))
    return tuple(_digest("seed", spec.base_seed, key, j) % _SEED_LIMIT for j in range(spec.n_seeds))


def expand(spec: SweepSpec | Mapping[str, Any] | str | os.PathLike[str]) -> list[Task]:
    """Every task of a sweep, in order: grid cells (last parameter fastest) x random samples x seeds.

    Parameters
    ----------
    spec : SweepSpec, mapping or path

    Returns
    -------
    list of Task
        ``spec.n_tasks`` tasks with distinct ``task_id``.
    """
    spec = _as_spec(spec)
    samples: list[dict[str, Scalar]] = [{}]
    if spec.random:
        drawn = {name: _draw(name, p, spec.n_samples, spec.base_seed) for name, p in spec.random.items()}
        samples = [{name: drawn[name][i] for name in spec.random} for i in range(spec.n_samples)]
    tasks: list[Task] = []
    names = list(spec.grid)
    for combo in itertools.product(*spec.grid.values()):
        for sample in samples:
            params = {**dict(zip(names, combo)), **sample, **spec.fixed}
            cell_id = format(_digest("cell", _canonical(params)), "016x")
            for seed in cell_seeds(spec, params):
                task_id = format(_digest("task", spec.experiment, _canonical(params), seed), "016x")
                tasks.append(Task(spec.experiment, params, int(seed), spec.metrics, task_id, cell_id))
    return tasks


# ------------------------------------------------------------------ one task
def resolve_experiment(path: str) -> Callable[[dict[str, Any], int], Mapping[str, Any]]:
    """Import ``"package.module:function"`` and return the function.

    Raises
    ------
    ConfigError
        The module cannot be imported or has no such callable (names ``experiment``).
    """
    module_name, _, attr = path.partition(":")
    try:
        obj: Any = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(
            f"experiment: cannot import module {module_name!r} ({type(exc).__name__}: {exc}); "
            "it must be importable here and on every worker (install it or set PYTHONPATH)"
        ) from None
    for part in (attr or "run").split("."):
        if not hasattr(obj, part):
            raise ConfigError(f"experiment: module {module_name!r} has no {attr or 'run'!r}")
        obj = getattr(obj, part)
    if not callable(obj):
        raise ConfigError(f"experiment: {path!r} is not callable")
    try:
        signature = inspect.signature(obj)
    except (TypeError, ValueError):  # a builtin without a signature: left to the first task
        return obj
    try:
        signature.bind({}, 0)
    except TypeError:
        raise ConfigError(f"experiment: {path!r} must take (params: dict, seed: int) and return a dict of metrics; its "
                          f"signature is {obj.__name__ if hasattr(obj, '__name__') else path}{signature}") from None
    return obj


def check_parameters(path: str, tasks: Sequence[Task]) -> None:
    """Check every cell's parameters with the experiment's own ``check_params``, if it declares one.

    An experiment module (``"package.module:function"``) may define
    ``check_params(params: dict)`` raising a project error for a value out of range;
    every canonical experiment of :mod:`cansim.experiments` does. Each distinct cell is
    checked once, before any worker starts.

    Raises
    ------
    ConfigError
        The first cell whose parameters the experiment refuses (named by its values).
    """
    module_name = path.partition(":")[0]
    check = getattr(importlib.import_module(module_name), "check_params", None)
    if not callable(check):
        return
    seen: set[str] = set()
    for task in tasks:
        if task.cell_id in seen:
            continue
        seen.add(task.cell_id)
        try:
            check(dict(task.params))
        except CansimError as exc:
            raise ConfigError(f"cell {task.params}: {exc}") from None


def _metric_value(name: str, value: Any) -> Scalar:
    if isinstance(value, np.generic) and np.ndim(value) == 0:
        value = value.item()
    if isinstance(value, (bool, int, float, str)):
        return value
    raise InvalidInputError(f"metric {name!r} is a {type(value).__name__}; metrics must be float, int, str or bool")


def _versions() -> dict[str, str]:
    import cansim

    return {
        "cansim_version": cansim.__version__,
        "numpy_version": np.__version__,
        "python_version": platform.python_version(),
    }


#: How a task's error names a metric its experiment did not return (:func:`run_task`; :func:`run` warns at the first).
_MISSING_METRIC = "missing from the experiment's result"


def run_task(task: Task) -> dict[str, Any]:
    """Run one task here (on a worker, or alone to reproduce a row) and return its row.

    The experiment's exceptions are caught: the row then has ``status="error"``, the
    exception in ``error`` and None metrics. Missing or non-scalar metrics are errors
    of the task too.

    Parameters
    ----------
    task : Task

    Returns
    -------
    dict
        Column -> value (see the module docstring).
    """
    t0 = time.perf_counter()
    values: dict[str, Any] = dict.fromkeys(task.metrics)
    status, error = "ok", ""
    try:
        fn = resolve_experiment(task.experiment)
        result = fn(dict(task.params), int(task.seed))
        if not isinstance(result, Mapping):
            raise InvalidInputError(f"the experiment returned a {type(result).__name__}, not a dict of metrics")
        missing = [m for m in task.metrics if m not in result]
        if missing:
            raise InvalidInputError(
                f"metric {missing[0]!r} {_MISSING_METRIC} (it returned {sorted(map(str, result))})"
            )
        values = {m: _metric_value(m, result[m]) for m in task.metrics}
    except Exception as exc:  # recorded in the row; the sweep goes on
        values = dict.fromkeys(task.metrics)
        status, error = "error", _one_line(exc)
    return {
        **task.params,
        "seed": task.seed,
        **values,
        "status": status,
        "error": error,
        "wall_time_s": time.perf_counter() - t0,
        "task_id": task.task_id,
        "cell_id": task.cell_id,
        "experiment": task.experiment,
        "hostname": socket.gethostname(),
        **_versions(),
        "finished_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _error_row(task: Task, exc: BaseException) -> dict[str, Any]:
    """A row for a task whose future failed outside the experiment (e.g. its worker kept dying)."""
    return {
        **task.params, "seed": task.seed, **dict.fromkeys(task.metrics), "status": "error", "error": _one_line(exc),
        "wall_time_s": math.nan, "task_id": task.task_id, "cell_id": task.cell_id, "experiment": task.experiment,
        "hostname": "", **_versions(),
        "finished_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }


# ------------------------------------------------------------------ storage
def _pa():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise missing_extra("a sweep (writing Parquet)", "pyarrow", "sweep") from None
    return pa, pq


def _write_atomic(table: Any, path: Path) -> None:
    _, pq = _pa()
    write_atomically(path, lambda fh: pq.write_table(table, fh))


def _write_part(out: Path, row: dict[str, Any]) -> None:
    pa, _ = _pa()
    parts = out / "parts"
    parts.mkdir(parents=True, exist_ok=True)
    _write_atomic(pa.Table.from_pylist([row]), parts / f"{row['task_id']}.parquet")


def _concat(tables: list[Any]) -> Any:
    """Rows of several tables in one; a column whose types cannot be unified (a metric that is a
    number in some rows and a string in others) is stored as strings."""
    pa, _ = _pa()
    try:
        return pa.concat_tables(tables, promote_options="permissive")
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        rows = [r for t in tables for r in t.to_pylist()]
        names = list(dict.fromkeys(n for t in tables for n in t.column_names))
        columns = {}
        for n in names:
            vals = [r.get(n) for r in rows]
            kinds = {_kind(v) for v in vals if v is not None}
            if len(kinds) > 1:
                log.warning("results column %r mixes %s values; stored as strings", n, " and ".join(sorted(kinds)))
                vals = [None if v is None else str(v) for v in vals]
            columns[n] = vals
        return pa.table(columns)


def read_results(out: str | os.PathLike[str]) -> Any:
    """The rows recorded in a sweep folder: ``results.parquet`` plus any parts not yet compacted.

    A task recorded twice (an errored task that was retried) keeps its latest row.
    An unreadable part file (a crash in the middle of writing it) is skipped with a
    warning, so its task runs again.

    Parameters
    ----------
    out : path
        The sweep's output folder.

    Returns
    -------
    pyarrow.Table
        Empty (no columns) when nothing was recorded yet.

    Raises
    ------
    CorruptFileError
        ``results.parquet`` exists but cannot be read.
    """
    pa, pq = _pa()
    out = Path(out)
    tables = []
    main = out / "results.parquet"
    if main.exists():
        try:
            tables.append(pq.read_table(main))
        except Exception as exc:
            raise CorruptFileError(
                f"cannot read it ({_one_line(exc)}); move it away to start the sweep afresh", path=main
            ) from None
    parts = out / "parts"
    if parts.is_dir():
        for p in sorted(parts.glob("*.parquet")):
            try:
                tables.append(pq.read_table(p))
            except Exception as exc:
                log.warning("skipping unreadable sweep part %s (%s); its task will run again", p, _one_line(exc))
    if not tables:
        return pa.table({})
    table = _concat(tables)
    if "task_id" not in table.column_names:
        raise CorruptFileError("no task_id column; not written by cansim.tools.sweep", path=main)
    ids = table.column("task_id").to_pylist()
    last = {tid: i for i, tid in enumerate(ids)}
    if len(last) != len(ids):
        table = table.take(sorted(last.values()))
    return table


def _compact(out: Path, order: Mapping[str, int]) -> Any:
    """Merge the parts into ``results.parquet`` (rows in spec order), then delete the parts."""
    table = read_results(out)
    if table.num_rows == 0:
        return table
    ids = table.column("task_id").to_pylist()
    idx = sorted(range(len(ids)), key=lambda i: (order.get(ids[i], len(order)), ids[i]))
    table = table.take(idx)
    _write_atomic(table, out / "results.parquet")
    parts = out / "parts"
    if parts.is_dir():
        for p in parts.glob("*.parquet"):
            p.unlink(missing_ok=True)
    return table


def _check_folder(out: Path, spec: SweepSpec) -> None:
    """Keep one sweep per folder: the experiment and the metrics of a re-run must match."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"out: {out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    meta = out / "spec.json"
    mine = {"experiment": spec.experiment, "metrics": list(spec.metrics)}
    if meta.exists():
        try:
            theirs = json.loads(meta.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise CorruptFileError(f"cannot read it ({_one_line(exc)}); delete it if the folder is yours", path=meta) from None
        for key in ("experiment", "metrics"):
            if theirs.get(key) != mine[key]:
                raise ConfigError(
                    f"{key}: {out} holds a sweep with {key} {theirs.get(key)!r}, not {mine[key]!r}; "
                    "use another --out folder"
                )
    else:
        text = json.dumps(mine, indent=2) + "\n"
        write_atomically(meta, lambda fh: fh.write(text.encode("utf-8")))


# ------------------------------------------------------------------ run
@dataclasses.dataclass(frozen=True)
class SweepResult:
    """Outcome of :func:`run`.

    Attributes
    ----------
    table : pyarrow.Table
        Every row recorded in ``path`` (this run's and earlier runs').
    path : pathlib.Path
        ``OUT/results.parquet``.
    ran : int
        Tasks run by this call.
    skipped : int
        Tasks already recorded, not run again.
    failed : int
        Tasks of this call that ended with ``status="error"``.
    """

    table: Any
    path: Path
    ran: int
    skipped: int
    failed: int

    @property
    def n_errors(self) -> int:
        """Rows of the whole table with ``status="error"``."""
        if self.table.num_rows == 0:
            return 0
        return sum(s == "error" for s in self.table.column("status").to_pylist())


def default_workers() -> int:
    """Worker processes of the default LocalCluster: the CPUs this process may use."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except AttributeError:  # not on Linux
        return max(os.cpu_count() or 1, 1)


def _client(address: str | None, workers: int | None, connect_timeout_s: float) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise missing_extra("a sweep (running on dask.distributed)", "distributed", "sweep") from None
    if address:
        try:
            return Client(address, timeout=connect_timeout_s), None
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"scheduler: cannot connect to {address} ({_one_line(exc)}); is the scheduler running?") from None
    n = default_workers() if workers is None else workers
    with _sigint_ignored():  # the worker processes inherit it (see _sigint_ignored)
        cluster = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.ERROR,
            env={"NUMBA_NUM_THREADS": "1"},  # one process per core: no nested thread pools
            # no dashboard; the scheduler's HTTP server (always started) on a free local port,
            # not Dask's 8787: with 8787 taken (another sweep, a Dask cluster) it warned on stderr
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        )
    return Client(cluster), cluster


@contextlib.contextmanager
def _sigint_ignored() -> Any:
    """Ignore SIGINT in this process while the local cluster's worker processes start.

    Ctrl-C in a terminal signals the whole process group: each worker process raised its
    own KeyboardInterrupt and printed a traceback (dozens per sweep) before this process's
    one-line message. A started process keeps an ignored SIGINT ignored (Python installs
    its KeyboardInterrupt handler only over the default disposition), so the workers leave
    the interrupt to this process, which cancels the tasks and closes the cluster. Only
    from the main thread (where signal handlers live); elsewhere nothing changes.

    The price: a Ctrl-C pressed during these seconds of start-up is ignored by this process
    too (press again once the progress bar shows). Blocking SIGINT instead of ignoring it
    would keep the press pending, but the worker processes are started by
    ``distributed``'s event-loop thread, which exists before this call and does not
    block it, so they would not inherit the block (measured: their ``SigBlk`` is 0);
    and a handler in this process is reset to the default in an ``exec``-ed worker,
    which would then print the traceback again.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


@contextlib.contextmanager
def _quiet_shutdown(interrupted: bool) -> Any:
    """After an interruption, Dask's scheduler warns about the cancelled tasks of each worker it
    removes while the cluster closes; those lines are not news to the user who pressed Ctrl-C."""
    loggers = [logging.getLogger(name) for name in ("distributed", "dask")] if interrupted else []
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.ERROR)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


def run(
    spec: SweepSpec | Mapping[str, Any] | str | os.PathLike[str],
    client: Any = None,
    out: str | os.PathLike[str] | None = None,
    progress: bool = True,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    retry_errors: bool = False,
    connect_timeout_s: float = 10.0,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> SweepResult:
    """Run a sweep on Dask, writing each finished task to ``out`` at once; resumes a sweep already there.

    Parameters
    ----------
    spec : SweepSpec, mapping or path
        The spec (a path is read with :func:`load_spec`).
    client : distributed.Client, optional
        Submit to this client. Otherwise ``scheduler`` (or the spec's) is connected
        to, or a LocalCluster of ``workers`` processes is started and closed at the end.
    out : path, optional
        Output folder (default ``./<spec name>``).
    progress : bool
        Show a tqdm bar (stderr) with done / failed / remaining.
    scheduler : str, optional
        ``tcp://HOST:PORT`` of a running Dask scheduler; overrides the spec's.
    workers : int, optional
        Worker processes of the default LocalCluster (default: :func:`default_workers`).
    retry_errors : bool
        Run tasks recorded with ``status="error"`` again (default: keep them).
    connect_timeout_s : float
        How long to wait for ``scheduler``, s.
    on_row : callable, optional
        Called with each finished row once it is on disk (live plots, logging).

    Returns
    -------
    SweepResult

    Raises
    ------
    ConfigError
        A malformed spec, an experiment that cannot be imported, an unreachable
        scheduler, or an ``out`` folder holding another sweep.
    CorruptFileError
        ``out`` holds an unreadable ``results.parquet`` or ``spec.json``.
    """
    spec = _as_spec(spec)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise InvalidInputError(f"workers must be an integer >= 1, got {workers!r}")
    if scheduler is not None and not _ADDRESS.match(str(scheduler)):
        raise ConfigError(f"scheduler: expected an address like 'tcp://HOST:PORT', got {scheduler!r}")
    if not (isinstance(connect_timeout_s, (int, float)) and connect_timeout_s > 0):
        raise InvalidInputError(f"connect_timeout_s must be > 0, got {connect_timeout_s!r}")
    resolve_experiment(spec.experiment)  # fail before anything starts
    _pa()
    out_dir = Path(out) if out is not None else Path.cwd() / spec.name
    _check_folder(out_dir, spec)

    tasks = expand(spec)
    check_parameters(spec.experiment, tasks)  # out-of-range values: exit 3 before the cluster, not 4 per task
    order = {t.task_id: i for i, t in enumerate(tasks)}
    done = read_results(out_dir)
    status: dict[str, str] = {}
    if done.num_rows:
        status = dict(zip(done.column("task_id").to_pylist(), done.column("status").to_pylist()))
    keep = {tid for tid, s in status.items() if s == "ok" or (s == "error" and not retry_errors)}
    todo = [t for t in tasks if t.task_id not in keep]
    skipped = len(tasks) - len(todo)
    failed = 0
    if todo:
        failed = _execute(todo, skipped, len(tasks), out_dir, client, scheduler or spec.scheduler, workers,
                          progress, connect_timeout_s, on_row)
    table = _compact(out_dir, order)
    return SweepResult(table=table, path=out_dir / "results.parquet", ran=len(todo), skipped=skipped, failed=failed)


def _execute(todo: list[Task], skipped: int, total: int, out: Path, client: Any, address: str | None,
             workers: int | None, progress: bool, connect_timeout_s: float,
             on_row: Callable[[dict[str, Any]], None] | None) -> int:
    own_client = own_cluster = None
    if client is None:
        own_client, own_cluster = _client(address, workers, connect_timeout_s)
        client = own_client
    from distributed import as_completed

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, initial=skipped, desc="sweep", unit="task", dynamic_ncols=True)
    failed = 0
    futures: dict[Any, Task] = {}
    interrupted = False
    warned_metric = False
    try:
        for t in todo:
            futures[client.submit(run_task, t, pure=False, key=f"cansim-sweep-{t.task_id}-{os.urandom(4).hex()}")] = t
        for fut in as_completed(list(futures)):
            task = futures[fut]
            try:
                row = fut.result()
            except Exception as exc:  # the task never returned a row (e.g. KilledWorker)
                row = _error_row(task, exc)
            _write_part(out, row)
            failed += row["status"] == "error"
            if not warned_metric and _MISSING_METRIC in row["error"]:  # most likely a misspelt metric: say so now,
                warned_metric = True  # not only in the results after the whole sweep
                log.warning("task %s: %s; if no cell returns it, stop (Ctrl-C keeps the tasks done), fix the spec's "
                            "metrics and run again with --retry-errors", task.task_id, row["error"])
            if bar is not None:
                bar.update(1)
                bar.set_postfix(failed=failed, remaining=bar.total - bar.n, refresh=False)
            fut.release()
            if on_row is not None:
                on_row(row)
    except BaseException as exc:
        interrupted = isinstance(exc, KeyboardInterrupt)
        for fut in futures:
            fut.cancel()
        raise
    finally:
        if bar is not None:
            bar.close()
        with _quiet_shutdown(interrupted):
            if own_client is not None:
                own_client.close()
            if own_cluster is not None:
                own_cluster.close()
    return failed
