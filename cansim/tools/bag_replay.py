"""Replay a logged robot run from a ROS bag into RatSLAM, without ROS.

Reads ROS1 ``.bag`` files and ROS2 bag folders (sqlite3 or mcap storage) with
``rosbags``: odometry from ``nav_msgs/Odometry`` (or ``geometry_msgs/TwistStamped`` /
``geometry_msgs/Twist``), camera images from ``sensor_msgs/Image`` or
``sensor_msgs/CompressedImage`` (decoded with Pillow), through the visual template
front end (:mod:`cansim.frontends.visual`) into :class:`cansim.models.ratslam.RatSLAM`
configured by an OpenRatSLAM config file (:meth:`RatSLAMConfig.from_file`).

Topics
------
As OpenRatSLAM's ROS nodes name them, under the ``topic_root`` key of the config
file's ``[general]`` section: odometry ``<topic_root>/odom``, images
``<topic_root>/camera/image`` (raw) or ``<topic_root>/camera/image/compressed``
(image_transport's compressed topic; the raw topic wins when a bag has both). An
empty ``topic_root`` gives ``/odom`` and ``/camera/image``. Both can be overridden.
A bag without them raises :class:`~cansim.errors.InvalidInputError` listing the topics
(and types) the bag has.

Pairing of images and odometry
------------------------------
As OpenRatSLAM's nodes see the messages when the bag is played: in the bag's record
(log) time order, each image is a view update (:meth:`RatSLAM.on_view`: matched
against the stored templates, its energy queued) and each odometry message an
odometry update (:meth:`RatSLAM.on_odo`: pose cells, experience map) with
``vtrans = twist.linear.x`` (m/s), ``vrot = twist.angular.z`` (rad/s) and ``dt`` the
difference of the message's header stamp and the previous odometry message's.
The first odometry message only starts the clock (OpenRatSLAM drops it: it has no
previous stamp). Messages recorded at the same log time are taken images first, as
:meth:`RatSLAM.step` does (view, then odometry). ``stamps="log"`` times the odometry
by the bag's record times instead of the header stamps (needed for
``geometry_msgs/Twist``, which has no header, and for recorders that leave the
header stamps unset).

Checks: the topics' message types; odometry stamps strictly increasing (non-zero in
header mode); finite speeds; every image of one size, of a supported encoding
(``mono8``, ``mono16``, ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``8UC1``, ``8UC3``,
``8UC4``; ``mono16`` is reduced to its high byte) and decodable. A message that
fails a check raises a typed error naming the topic and the message's index.

Outputs (:func:`write_outputs`): ``experience_map.npz`` (:meth:`ExperienceMap.save`),
``trajectory.csv`` (``time_s,x_m,y_m,th_rad,exp_id``: one row per odometry update
once the map has its first experience; the pose is that experience's pose in the
final, relaxed map) and ``experience_map.png`` (:func:`maps.plot_maps.plot_experience_map`).
"""

from __future__ import annotations

import csv
import io
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from cansim.errors import ConfigError, CorruptFileError, InvalidInputError, missing_extra
from cansim.frontends.visual import VisualTemplateConfig
from cansim.models.openratslam_config import REPLAY_KEYS
from cansim.models.ratslam import RatSLAM
from cansim.models.ratslam_config import RatSLAMConfig

__all__ = [
    "ODOMETRY_TYPES",
    "IMAGE_TYPES",
    "ReplayTopics",
    "ReplayResult",
    "topic_root",
    "default_topics",
    "decode_image",
    "replay",
    "write_outputs",
]

ODOMETRY_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/TwistStamped", "geometry_msgs/msg/Twist")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")
_CHANNELS = {"mono8": 1, "8uc1": 1, "mono16": 2, "16uc1": 2, "rgb8": 3, "bgr8": 3, "8uc3": 3,
             "rgba8": 4, "bgra8": 4, "8uc4": 4}


def _need_rosbags() -> Any:
    try:
        import rosbags.highlevel  # noqa: F401
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise missing_extra("bag replay (reading bags)", "rosbags", "bags") from None
    return Stores, get_typestore


# ------------------------------------------------------------------ topics
def topic_root(text: str) -> str:
    """The ``topic_root`` of the ``[general]`` section of an OpenRatSLAM config text ("" when absent)."""
    section = ""
    for raw in text.splitlines():
        line = raw.strip()
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1].strip()
        elif section == "general" and "=" in line and line.split("=", 1)[0].strip() == "topic_root":
            return line.split("=", 1)[1].strip()
    return ""


def _join(root: str, suffix: str) -> str:
    parts = [p for p in (root + "/" + suffix).split("/") if p]
    return "/" + "/".join(parts)


def default_topics(root: str) -> tuple[str, tuple[str, str]]:
    """OpenRatSLAM's topic names under ``root``: odometry, and (raw image, compressed image)."""
    return _join(root, "odom"), (_join(root, "camera/image"), _join(root, "camera/image/compressed"))


def _norm(topic: str) -> str:
    return _join("", topic)


@dataclass(frozen=True)
class ReplayTopics:
    """The topics a replay reads, with their message types."""

    odometry: str
    odometry_type: str
    image: str
    image_type: str


# ------------------------------------------------------------------ images
def decode_image(msg: Any, msgtype: str) -> np.ndarray:
    """A ``sensor_msgs/Image`` or ``CompressedImage`` message as a uint8 array.

    Parameters
    ----------
    msg : deserialised message
    msgtype : str
        ``"sensor_msgs/msg/Image"`` or ``"sensor_msgs/msg/CompressedImage"``.

    Returns
    -------
    ndarray of uint8, shape (H, W) (grey) or (H, W, 3) (colour; RGB or BGR order,
    the visual front end averages the channels)

    Raises
    ------
    InvalidInputError
        An unsupported encoding.
    CorruptFileError
        Data shorter than its declared size, or a compressed image that cannot be decoded.
    """
    if msgtype.endswith("CompressedImage"):
        try:
            from PIL import Image
        except ImportError:
            raise missing_extra("decoding a CompressedImage", "PIL (Pillow)", "bags") from None
        try:
            with Image.open(io.BytesIO(bytes(msg.data))) as im:
                im.load()
                grey = im.mode in ("1", "L", "LA", "I", "I;16", "I;16B", "I;16L", "F")
                arr = np.asarray(im.convert("L" if grey else "RGB"))
        except Exception as exc:
            raise CorruptFileError(f"compressed image ({msg.format!r}) cannot be decoded: {exc}") from None
        return np.ascontiguousarray(arr, dtype=np.uint8)
    enc = str(msg.encoding).lower()
    if enc not in _CHANNELS:
        raise InvalidInputError(
            f"image encoding {msg.encoding!r} is not supported; use one of {', '.join(sorted(_CHANNELS))} "
            "(or a CompressedImage topic)"
        )
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    nbytes = _CHANNELS[enc]
    ch = 1 if nbytes == 2 else nbytes
    data = np.asarray(msg.data, dtype=np.uint8)
    if h < 1 or w < 1:
        raise CorruptFileError(f"image of {h} x {w} px ({msg.encoding}): an image needs at least one row and column")
    if step < w * nbytes:
        raise CorruptFileError(f"image of {h} x {w} px, {msg.encoding}: its row step {step} is shorter than a row "
                               f"({w} px x {nbytes} bytes = {w * nbytes}); the encoding or the step is wrong")
    if data.size < step * h:
        raise CorruptFileError(f"image of {h} x {w} px, {msg.encoding}, step {step} needs {step * h} bytes, the "
                               f"message has {data.size}")
    rows = data[: step * h].reshape(h, step)[:, : w * nbytes]
    if nbytes == 2:  # 16-bit grey -> its high byte
        hi = rows.reshape(h, w, 2)[:, :, 0 if msg.is_bigendian else 1]
        return np.ascontiguousarray(hi)
    img = rows.reshape(h, w, ch) if ch > 1 else rows.reshape(h, w)
    if ch == 4:
        img = img[:, :, :3]
    return np.ascontiguousarray(img)


# ------------------------------------------------------------------ replay
@dataclass
class ReplayResult:
    """What a replay produced.

    Attributes
    ----------
    slam : RatSLAM
        The model after the last message (its ``experience_map`` is the map).
    stamp_ns : ndarray (n,) of int64
        Time of each odometry update, ns (header stamps or record times, see ``stamps``).
    exp_ids : ndarray (n,) of int
        The current experience after each odometry update (-1 before the first).
    topics : ReplayTopics
    n_odometry, n_images : int
        Messages read from each topic.
    files : dict
        Output name -> path, once :func:`write_outputs` ran.
    """

    slam: RatSLAM
    stamp_ns: np.ndarray
    exp_ids: np.ndarray
    topics: ReplayTopics
    n_odometry: int
    n_images: int
    files: dict[str, Path] = field(default_factory=dict)

    @property
    def time_s(self) -> np.ndarray:
        """``stamp_ns`` in seconds, shape (n,)."""
        return self.stamp_ns / 1e9

    def trajectory(self) -> np.ndarray:
        """Rows ``(time_s, x_m, y_m, th_rad, exp_id)`` once the map has an experience; shape (m, 5).

        The pose is the current experience's pose in the final (relaxed) map.
        """
        keep = self.exp_ids >= 0
        ids = self.exp_ids[keep]
        poses = self.slam.experience_map.poses[ids] if len(ids) else np.zeros((0, 3))
        return np.column_stack([self.time_s[keep], poses[:, :3], ids.astype(np.float64)])


def _openratslam_fields() -> dict[str, Any]:
    """The fields :meth:`RatSLAMConfig.openratslam` sets otherwise than the defaults (engine, frame, dtype, ...)."""
    preset, base = RatSLAMConfig.openratslam(), RatSLAMConfig()
    return {name: getattr(preset, name) for name in preset.to_dict() if getattr(preset, name) != getattr(base, name)}


def _load_config(config: str | os.PathLike[str] | RatSLAMConfig | None,
                 openratslam: bool = False) -> tuple[RatSLAMConfig, str]:
    if openratslam and isinstance(config, RatSLAMConfig):
        raise ConfigError("openratslam=True applies to a config file (or none); a RatSLAMConfig is used as given - "
                          "build it with RatSLAMConfig.openratslam(...)")
    preset = _openratslam_fields() if openratslam else {}
    if config is None:
        return RatSLAMConfig(frontend=VisualTemplateConfig(), **preset), ""
    if isinstance(config, RatSLAMConfig):
        if not isinstance(config.frontend, VisualTemplateConfig):
            raise ConfigError(
                f"frontend: a bag replay feeds camera images, so it must be a VisualTemplateConfig, not {config.frontend!r}"
            )
        return config, ""
    path = Path(config)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such OpenRatSLAM config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read it as a text config file ({exc})") from None
    root = topic_root(text)
    # topic_root is read here, not by the model: a comment in its place (the other keys keep their line numbers),
    # so that RatSLAMConfig's warning names only the keys nothing reads
    model_text = "\n".join("#" if ln.split("=", 1)[0].strip() in REPLAY_KEYS and "=" in ln else ln
                            for ln in text.split("\n"))
    try:
        cfg = RatSLAMConfig.from_text(model_text, **preset)  # an OpenRatSLAM file's front end is visual
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    return cfg, root


def _bag_paths(bag: str | os.PathLike[str]) -> list[Path]:
    p = Path(bag)
    if not p.exists():
        raise InvalidInputError(f"{p}: no such bag file or folder")
    if p.is_dir() and not (p / "metadata.yaml").exists():
        bags = sorted(p.glob("*.bag"))
        if bags:
            return bags
        raise InvalidInputError(
            f"{p}: neither a ROS2 bag folder (no metadata.yaml) nor a folder of ROS1 .bag files"
        )
    if p.is_file() and p.suffix != ".bag":
        raise InvalidInputError(f"{p}: a ROS1 bag file ends in .bag; for a ROS2 bag give its folder")
    return [p]


def _topic_list(topics: dict[str, str]) -> str:
    return ", ".join(f"{t} ({ty})" for t, ty in sorted(topics.items())) or "none"


def _pick(topics: dict[str, str], given: str | None, defaults: tuple[str, ...], kinds: tuple[str, ...],
          what: str, option: str, bag: str) -> str:
    wanted = (_norm(given),) if given else defaults
    for t in wanted:
        if t in topics:
            if topics[t] not in kinds:
                raise InvalidInputError(
                    f"{bag}: topic {t} has type {topics[t]}, expected {' or '.join(kinds)}"
                )
            return t
    raise InvalidInputError(
        f"{bag}: no {what} topic {' or '.join(wanted)}; the bag has: {_topic_list(topics)}. "
        f"Set topic_root in the config's [general] section or pass {option}"
    )


def _stamp_ns(msg: Any) -> int:
    s = msg.header.stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def _twist(msg: Any, msgtype: str) -> tuple[float, float]:
    if msgtype == "nav_msgs/msg/Odometry":
        tw = msg.twist.twist
    elif msgtype == "geometry_msgs/msg/TwistStamped":
        tw = msg.twist
    else:
        tw = msg
    return float(tw.linear.x), float(tw.angular.z)


def _records(reader: Any, conns: list[Any], name: str) -> Iterator[tuple[Any, int, bytes]]:
    """The reader's raw messages; a damaged or truncated bag is a CorruptFileError."""
    it = iter(reader.messages(connections=conns))
    while True:
        try:
            item = next(it)
        except StopIteration:
            return
        except Exception as exc:  # rosbags' reader errors, struct/zstd/lz4/sqlite errors of a damaged file
            raise CorruptFileError(
                f"reading its messages failed ({type(exc).__name__}: {exc}); the bag is truncated or damaged", path=name
            ) from None
        yield item


def _messages(reader: Any, conns: list[Any], image_topic: str, name: str) -> Iterator[tuple[Any, int, bytes]]:
    """The reader's messages in log-time order; at one log time, images first (view, then odometry)."""
    batch: list[tuple[Any, int, bytes]] = []
    for conn, t, raw in _records(reader, conns, name):
        if batch and t != batch[0][1]:
            batch.sort(key=lambda m: _norm(m[0].topic) != image_topic)  # stable
            yield from batch
            batch = []
        batch.append((conn, t, raw))
    batch.sort(key=lambda m: _norm(m[0].topic) != image_topic)
    yield from batch


def replay(
    bag: str | os.PathLike[str],
    config: str | os.PathLike[str] | RatSLAMConfig | None = None,
    *,
    odometry_topic: str | None = None,
    image_topic: str | None = None,
    stamps: str = "header",
    progress: bool = False,
    openratslam: bool = False,
) -> ReplayResult:
    """Run RatSLAM over a bag's odometry and camera images (pairing in the module docstring).

    Parameters
    ----------
    bag : path
        A ROS1 ``.bag`` file, a folder of them, or a ROS2 bag folder (sqlite3 or mcap).
    config : path or RatSLAMConfig, optional
        An OpenRatSLAM ``config_*.txt`` file (its ``topic_root`` names the topics; its
        front end is visual) or a config whose ``frontend`` is a
        :class:`~cansim.frontends.visual.VisualTemplateConfig`. Default:
        ``RatSLAMConfig(frontend=VisualTemplateConfig())`` and topic root "".
    odometry_topic, image_topic : str, optional
        Override the topics derived from ``topic_root``.
    stamps : {"header", "log"}
        Time the odometry by its header stamps (OpenRatSLAM) or by the record times.
    progress : bool
        Show a tqdm bar (stderr).
    openratslam : bool
        Read the config file (or none) into :meth:`RatSLAMConfig.openratslam`'s preset: the
        C++ core's pose cells bit for bit, its frame, float64, unbounded relaxation, its link
        timer and at most one cell a step (``cansim replay --openratslam``). Default: the
        defaults of :class:`RatSLAMConfig` (the generic pose-cell engine, any backend).

    Returns
    -------
    ReplayResult

    Raises
    ------
    InvalidInputError
        Missing topics (the message lists the bag's topics), wrong message types, out
        of order or unset time stamps, non-finite speeds, images of changing size.
    CorruptFileError
        A file that is not a readable bag, or a message that cannot be decoded.
    ConfigError
        A malformed config file.
    """
    if stamps not in ("header", "log"):
        raise InvalidInputError(f"stamps must be 'header' or 'log', got {stamps!r}")
    cfg, root = _load_config(config, openratslam)
    paths = _bag_paths(bag)
    Stores, get_typestore = _need_rosbags()
    from rosbags.highlevel import AnyReader

    name = str(bag)
    try:
        reader = AnyReader(paths, default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags' reader errors: not a bag, truncated, unknown storage
        raise CorruptFileError(f"cannot open it as a ROS bag ({type(exc).__name__}: {exc})", path=name) from None
    try:
        types: dict[str, set[str]] = {}
        for c in reader.connections:
            if not (isinstance(c.topic, str) and isinstance(c.msgtype, str)):  # a hand-edited metadata.yaml
                raise CorruptFileError(f"a topic's name and type must be text, got name {c.topic!r} and type "
                                       f"{c.msgtype!r}; check the bag's metadata.yaml", path=name)
            types.setdefault(_norm(c.topic), set()).add(c.msgtype)
        topics = {t: " + ".join(sorted(ty)) for t, ty in types.items()}  # several types on one topic: refused below
        odo_default, img_defaults = default_topics(root)
        odo_t = _pick(topics, odometry_topic, (odo_default,), ODOMETRY_TYPES, "odometry", "--odom-topic", name)
        img_t = _pick(topics, image_topic, img_defaults, IMAGE_TYPES, "image", "--image-topic", name)
        odo_type, img_type = topics[odo_t], topics[img_t]
        if stamps == "header" and odo_type == "geometry_msgs/msg/Twist":
            raise InvalidInputError(f"{name}: {odo_t} is geometry_msgs/Twist, which has no header stamp; use stamps='log'")
        conns = [c for c in reader.connections if _norm(c.topic) in (odo_t, img_t)]
        n_msgs = sum(c.msgcount for c in conns)
        result = _run(reader, conns, cfg, odo_t, odo_type, img_t, img_type, stamps, progress, n_msgs, name)
    finally:
        try:
            reader.close()
        except Exception:  # a damaged file may fail to close too; the error that matters is raised above
            pass
    return result


def _run(reader: Any, conns: list[Any], cfg: RatSLAMConfig, odo_t: str, odo_type: str, img_t: str, img_type: str,
         stamps: str, progress: bool, n_msgs: int, name: str) -> ReplayResult:
    slam = RatSLAM(cfg)
    times: list[int] = []
    exp_ids: list[int] = []
    prev_ns: int | None = None
    n_odo = n_img = 0
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_msgs, desc="replay", unit="msg", dynamic_ncols=True)
    try:
        for conn, log_ns, raw in _messages(reader, conns, img_t, name):
            topic = _norm(conn.topic)
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:
                index = n_img if topic == img_t else n_odo
                raise CorruptFileError(f"{topic} message {index} cannot be deserialised: {exc}", path=name) from None
            if topic == img_t:
                try:
                    image = decode_image(msg, img_type)
                except CorruptFileError as exc:
                    raise CorruptFileError(f"{topic} message {n_img}: {exc}", path=name) from None
                except InvalidInputError as exc:
                    raise type(exc)(f"{name}: {topic} message {n_img}: {exc}") from None
                try:
                    slam.on_view(image)
                except InvalidInputError as exc:
                    raise type(exc)(f"{name}: {topic} message {n_img} (image {image.shape}): {exc}") from None
                n_img += 1
            else:
                t_ns = log_ns if stamps == "log" else _stamp_ns(msg)
                if stamps == "header" and t_ns <= 0:
                    raise InvalidInputError(
                        f"{name}: {topic} message {n_odo} has no header stamp (0); replay with stamps='log' "
                        "(command line: --stamps log) to time it by the record time"
                    )
                v, w = _twist(msg, odo_type)
                if not (math.isfinite(v) and math.isfinite(w)):
                    raise InvalidInputError(f"{name}: {topic} message {n_odo}: non-finite speed (vtrans {v}, vrot {w})")
                if prev_ns is not None:
                    if t_ns <= prev_ns:
                        raise InvalidInputError(
                            f"{name}: {topic} message {n_odo}: stamp {t_ns / 1e9:.9f} s is not after the previous "
                            f"odometry's {prev_ns / 1e9:.9f} s; odometry must be in time order"
                            + (" (or replay with stamps='log')" if stamps == "header" else "")
                        )
                    try:
                        state = slam.on_odo(v, w, (t_ns - prev_ns) / 1e9)
                    except InvalidInputError as exc:
                        raise type(exc)(f"{name}: {topic} message {n_odo}: {exc}") from None
                    times.append(t_ns)
                    exp_ids.append(state.exp_id)
                prev_ns = t_ns
                n_odo += 1
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    if n_odo < 2 or n_img < 1:
        raise InvalidInputError(
            f"{name}: {n_odo} odometry message(s) on {odo_t} and {n_img} image(s) on {img_t}; "
            "a replay needs at least 2 odometry messages and 1 image"
        )
    topics = ReplayTopics(odo_t, odo_type, img_t, img_type)
    return ReplayResult(slam, np.asarray(times, dtype=np.int64), np.asarray(exp_ids, dtype=np.int64), topics, n_odo, n_img)


def write_outputs(result: ReplayResult, out: str | os.PathLike[str], *, title: str | None = None) -> dict[str, Path]:
    """Write ``experience_map.npz``, ``trajectory.csv`` and ``experience_map.png`` into ``out``.

    Parameters
    ----------
    result : ReplayResult
    out : path
        Output folder (created).
    title : str, optional
        Figure title.

    Returns
    -------
    dict
        ``{"map": ..., "trajectory": ..., "figure": ...}`` paths (also set on ``result.files``).
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"{out} exists and is not a folder")
    out.mkdir(parents=True, exist_ok=True)
    em = result.slam.experience_map
    files = {"map": out / "experience_map.npz", "trajectory": out / "trajectory.csv", "figure": out / "experience_map.png"}
    em.save(files["map"])
    with open(files["trajectory"], "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["time_s", "x_m", "y_m", "th_rad", "exp_id"])
        keep = result.exp_ids >= 0
        for ns, (_, x, y, th, eid) in zip(result.stamp_ns[keep], result.trajectory()):
            w.writerow([f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d}", repr(float(x)), repr(float(y)),
                        repr(float(th)), int(eid)])
    import matplotlib.pyplot as plt

    from maps.plot_maps import plot_experience_map

    fig = plot_experience_map(em)
    fig.axes[0].set_title(title or f"Experience map ({em.n_experiences} experiences, {em.n_links} links)")
    fig.savefig(files["figure"], dpi=120)
    plt.close(fig)
    result.files = dict(files)
    return files

