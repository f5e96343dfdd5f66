"""ROS bag replay without ROS: bags written with rosbags from a synthetic run replay to
the same experience map as feeding the same odometry and images to RatSLAM directly."""

from __future__ import annotations

import csv
import io
import re

import numpy as np
import pytest

pytest.importorskip("rosbags")
pytestmark = pytest.mark.filterwarnings("ignore:OpenRatSLAM config key 'enable'")

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from cansim.tools.bag_replay import decode_image, default_topics, replay, topic_root, write_outputs
from cansim.errors import ConfigError, CorruptFileError, InvalidInputError
from cansim.frontends.visual import VisualTemplateConfig
from cansim.models.ratslam import RatSLAM, RatSLAMConfig
from cansim.testing.worlds import LoopRoute, make_run, render_view, scatter_landmarks

ROUTE = LoopRoute(step_m=0.1)
CFG_TEXT = """[general]
topic_root=irat_red

[ratslam]
pc_cell_x_size = 0.1
template_x_size = 24
template_y_size = 4
vt_shift_match = 2
vt_step_match = 1
vt_match_threshold = 0.02

[draw]
enable=0
"""
T0_NS = 1_700_000_000 * 10**9  # a plausible epoch stamp
DT_NS = 100_000_000  # 10 Hz


@pytest.fixture(scope="module")
def synthetic():
    run = make_run(ROUTE, loops=(1, 1), seed=5)
    lm = scatter_landmarks(ROUTE, seed=1)
    images = [render_view(p, lm, shape=(12, 48)) for p in run.truth]
    return run, images


@pytest.fixture()
def config_file(tmp_path):
    path = tmp_path / "config_test.txt.in"
    path.write_text(CFG_TEXT)
    return path


def _config():
    return RatSLAMConfig(cell_size_m=0.1, frontend=VisualTemplateConfig(
        template_width_blocks=24, template_height_blocks=4, shift_match_blocks=2, step_match_blocks=1, match_threshold=0.02))


def _speeds(run, k):
    """Odometry k as recorded at 10 Hz: the same displacement per step as the synthetic run's."""
    dt = DT_NS / 1e9
    return run.vtrans[k] * run.dt / dt, run.vrot[k] * run.dt / dt


def direct(run, images, config=None):
    """The documented pairing fed by hand: image k is a view, odometry k an odometry update, except
    that odometry message 0 only starts the clock (dt of message k = its stamp - message k-1's)."""
    slam = RatSLAM(config or _config())
    slam.on_view(images[0])
    for k in range(1, len(run)):
        slam.on_view(images[k])
        slam.on_odo(*_speeds(run, k), DT_NS / 1e9)
    return slam


# ------------------------------------------------------------------ bag writers
def _time(ts, ns):
    return ts.types["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _header(ts, ns, ros1, frame="odom"):
    H = ts.types["std_msgs/msg/Header"]
    return H(seq=0, stamp=_time(ts, ns), frame_id=frame) if ros1 else H(stamp=_time(ts, ns), frame_id=frame)


def _odometry(ts, ns, v, w, ros1):
    T = ts.types
    vec = T["geometry_msgs/msg/Vector3"]
    pose = T["geometry_msgs/msg/PoseWithCovariance"](
        pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                         orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
        covariance=np.zeros(36))
    twist = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](linear=vec(x=float(v), y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=float(w))),
        covariance=np.zeros(36))
    return T["nav_msgs/msg/Odometry"](header=_header(ts, ns, ros1), child_frame_id="base_link", pose=pose, twist=twist)


def _raw_image(ts, ns, img, ros1):
    h, w = img.shape
    return ts.types["sensor_msgs/msg/Image"](header=_header(ts, ns, ros1, "camera"), height=h, width=w, encoding="mono8",
                                             is_bigendian=0, step=w, data=img.ravel().copy())


def _png_image(ts, ns, img, ros1):
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")  # lossless, so the replay sees the same pixels
    return ts.types["sensor_msgs/msg/CompressedImage"](header=_header(ts, ns, ros1, "camera"), format="png",
                                                       data=np.frombuffer(buf.getvalue(), dtype=np.uint8).copy())


def _messages(run, images, compressed, ros1, ts, root="/irat_red", n=None):
    """(topic, type, log time ns, message) in recording order: image k then odometry k at one time stamp."""
    odo_t, (raw_t, comp_t) = default_topics(root)
    img_t, img_type = (comp_t, "sensor_msgs/msg/CompressedImage") if compressed else (raw_t, "sensor_msgs/msg/Image")
    out = []
    for k in range(len(run) if n is None else n):
        ns = T0_NS + k * DT_NS
        img = (_png_image if compressed else _raw_image)(ts, ns, images[k], ros1)
        odo = _odometry(ts, ns, *_speeds(run, k), ros1)
        out.append((img_t, img_type, ns, img))
        out.append((odo_t, "nav_msgs/msg/Odometry", ns, odo))
    return out


def write_ros1(path, messages):
    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer1(path) as w:
        conns = {}
        for topic, typ, ns, msg in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], ns, ts.serialize_ros1(msg, typ))


def write_ros2(path, messages, storage):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer2(path, version=9, storage_plugin=storage) as w:
        conns = {}
        for topic, typ, ns, msg in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=ts)
            w.write(conns[topic], ns, ts.serialize_cdr(msg, typ))


def _map_arrays(slam):
    return {k: np.asarray(v) for k, v in slam.experience_map.to_arrays().items()}


def assert_same_map(a, b):
    ma, mb = _map_arrays(a), _map_arrays(b)
    assert ma.keys() == mb.keys()
    for k in ma:
        assert np.array_equal(ma[k], mb[k]), k


# ------------------------------------------------------------------ tests
@pytest.mark.parametrize("kind", ["ros1-raw", "ros2-sqlite3-png", "ros2-mcap-raw"])
def test_replay_equals_feeding_the_same_odometry_and_images(kind, synthetic, config_file, tmp_path):
    run, images = synthetic
    compressed = kind.endswith("png")
    if kind.startswith("ros1"):
        msgs = _messages(run, images, compressed, True, get_typestore(Stores.ROS1_NOETIC))
        bag = tmp_path / "run.bag"
        write_ros1(bag, msgs)
    else:
        msgs = _messages(run, images, compressed, False, get_typestore(Stores.ROS2_HUMBLE))
        bag = tmp_path / "run_bag"
        write_ros2(bag, msgs, StoragePlugin.MCAP if "mcap" in kind else StoragePlugin.SQLITE3)
    result = replay(bag, config_file)
    want = direct(run, images)
    assert result.n_odometry == len(run) and result.n_images == len(run)
    assert result.topics.odometry == "/irat_red/odom"
    assert result.topics.image == ("/irat_red/camera/image/compressed" if compressed else "/irat_red/camera/image")
    assert want.experience_map.n_experiences > 10 and want.n_views < len(run)  # a real map: templates re-used
    assert_same_map(result.slam, want)
    assert result.slam.n_views == want.n_views

    files = write_outputs(result, tmp_path / "out")
    from maps.experience_map import ExperienceMap

    loaded = ExperienceMap.load(files["map"])
    assert np.array_equal(loaded.poses, want.experience_map.poses)
    with open(files["trajectory"], newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["time_s", "x_m", "y_m", "th_rad", "exp_id"]
    assert len(rows) == len(run) - 1  # odometry message 0 only starts the clock
    assert rows[0]["time_s"] == "1700000000.100000000"  # the header stamp of odometry message 1, exactly
    assert rows[-1]["time_s"] == f"{1_700_000_000 + (len(run) - 1) // 10}.{(len(run) - 1) % 10}00000000"
    last = int(rows[-1]["exp_id"])
    assert last == want.experience_map.current_id
    assert [float(rows[-1][c]) for c in ("x_m", "y_m", "th_rad")] == pytest.approx(list(want.experience_map.poses[last]))
    assert files["figure"].stat().st_size > 5_000


def test_bag_without_the_topics_lists_the_topics_it_has(synthetic, tmp_path):
    run, images = synthetic
    ts = get_typestore(Stores.ROS1_NOETIC)
    msgs = _messages(run, images, False, True, ts, root="/robot", n=3)
    write_ros1(tmp_path / "other.bag", msgs)
    with pytest.raises(InvalidInputError) as info:
        replay(tmp_path / "other.bag", _config())  # no topic root: /odom, /camera/image "": /odom, /camera/image
    text = str(info.value)
    assert "/odom" in text and "/robot/odom (nav_msgs/msg/Odometry)" in text
    assert "/robot/camera/image (sensor_msgs/msg/Image)" in text
    # the same bag with the right topics replays
    assert replay(tmp_path / "other.bag", _config(), odometry_topic="/robot/odom", image_topic="/robot/camera/image").n_odometry == 3


def test_wrong_message_type_and_out_of_order_stamps_are_refused(synthetic, tmp_path):
    run, images = synthetic
    ts = get_typestore(Stores.ROS1_NOETIC)
    msgs = _messages(run, images, False, True, ts, root="", n=4)
    odometry_only = [m for m in msgs if "odom" in m[0]]
    write_ros1(tmp_path / "typed.bag", odometry_only)
    with pytest.raises(InvalidInputError, match="no image topic"):
        replay(tmp_path / "typed.bag", _config())
    write_ros1(tmp_path / "wrongtype.bag", odometry_only + [("/camera/image", ty, ns + 1, m) for _, ty, ns, m in odometry_only])
    with pytest.raises(InvalidInputError, match=r"topic /camera/image has type nav_msgs/msg/Odometry, expected sensor_msgs"):
        replay(tmp_path / "wrongtype.bag", _config())
    # odometry whose header stamps go backwards (recorded in log order)
    back = []
    for i, (t, ty, ns, m) in enumerate(msgs):
        if "odom" in t and i == 5:
            m = _odometry(ts, ns - 3 * DT_NS, 0.1, 0.0, True)
        back.append((t, ty, ns, m))
    write_ros1(tmp_path / "back.bag", back)
    with pytest.raises(InvalidInputError, match=r"/odom message 2: stamp .* is not after"):
        replay(tmp_path / "back.bag", _config())
    # ... which stamps="log" accepts (the record times increase)
    assert replay(tmp_path / "back.bag", _config(), stamps="log").n_odometry == 4


def test_unset_header_stamps_ask_for_log_time(synthetic, tmp_path):
    run, images = synthetic
    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs = [(t, ty, ns, _odometry(ts, 0, 0.1, 0.0, False) if "odom" in t else m)
            for t, ty, ns, m in _messages(run, images, False, False, ts, root="", n=3)]
    write_ros2(tmp_path / "nostamp", msgs, StoragePlugin.MCAP)
    with pytest.raises(InvalidInputError, match="no header stamp"):
        replay(tmp_path / "nostamp", _config())
    res = replay(tmp_path / "nostamp", _config(), stamps="log")
    assert res.time_s == pytest.approx([(T0_NS + DT_NS) / 1e9, (T0_NS + 2 * DT_NS) / 1e9])


def test_not_a_bag_and_missing_paths_are_typed_errors(tmp_path):
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 10)
    with pytest.raises(CorruptFileError):
        replay(junk)
    with pytest.raises(InvalidInputError, match="no such bag"):
        replay(tmp_path / "missing.bag")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InvalidInputError, match="neither a ROS2 bag folder"):
        replay(tmp_path / "empty")


def test_topic_names_follow_openratslam():
    assert topic_root(CFG_TEXT) == "irat_red"
    assert topic_root("[ratslam]\ntopic_root=x\n") == ""  # only [general] counts
    assert default_topics("irat_red") == ("/irat_red/odom", ("/irat_red/camera/image", "/irat_red/camera/image/compressed"))
    assert default_topics("/newcollege/")[0] == "/newcollege/odom"
    assert default_topics("")[0] == "/odom"


class _Img:
    def __init__(self, **kw):
        self.__dict__.update(kw)


def test_decode_image_encodings():
    grey = np.arange(12, dtype=np.uint8).reshape(3, 4)
    padded = np.zeros((3, 6), dtype=np.uint8)
    padded[:, :4] = grey
    got = decode_image(_Img(height=3, width=4, step=6, encoding="mono8", is_bigendian=0, data=padded.ravel()), "sensor_msgs/msg/Image")
    assert np.array_equal(got, grey)
    rgba = np.dstack([grey, grey + 1, grey + 2, np.full_like(grey, 255)])
    got = decode_image(_Img(height=3, width=4, step=16, encoding="rgba8", is_bigendian=0, data=rgba.ravel()), "sensor_msgs/msg/Image")
    assert np.array_equal(got, rgba[:, :, :3])
    wide = (grey.astype(np.uint16) << 8) | 7
    got = decode_image(_Img(height=3, width=4, step=8, encoding="mono16", is_bigendian=0,
                            data=np.frombuffer(wide.astype("<u2").tobytes(), dtype=np.uint8)), "sensor_msgs/msg/Image")
    assert np.array_equal(got, grey)
    with pytest.raises(InvalidInputError, match="bayer_rggb8"):
        decode_image(_Img(height=3, width=4, step=4, encoding="bayer_rggb8", is_bigendian=0, data=grey.ravel()), "sensor_msgs/msg/Image")
    with pytest.raises(CorruptFileError):
        decode_image(_Img(format="jpeg", data=np.frombuffer(b"not a jpeg", dtype=np.uint8)), "sensor_msgs/msg/CompressedImage")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(0, 5), w=st.integers(0, 5), extra=st.integers(-3, 3), n=st.integers(0, 80),
       enc=st.sampled_from(["mono8", "rgb8", "bgra8", "mono16", "8UC3"]))
def test_decode_image_never_returns_a_wrong_size(h, w, extra, n, enc):
    """Any header / data length either decodes to an (h, w[, 3]) uint8 image or raises a typed error."""
    data = np.arange(n, dtype=np.uint8)
    nbytes = {"mono8": 1, "rgb8": 3, "bgra8": 4, "mono16": 2, "8UC3": 3}[enc]
    msg = _Img(height=h, width=w, step=w * nbytes + extra, encoding=enc, is_bigendian=0, data=data)
    try:
        img = decode_image(msg, "sensor_msgs/msg/Image")
    except (CorruptFileError, InvalidInputError) as exc:
        text = str(exc)
        if h >= 1 and w >= 1 and enc != "8UC3" and extra < 0:  # the message names the real fault, never "needs 96, has 96"
            assert "shorter than a row" in text
        got = re.search(r"needs (\d+) bytes, the message has (\d+)", text)
        assert got is None or int(got[1]) > int(got[2])
        return
    assert img.dtype == np.uint8 and img.shape[:2] == (h, w)
    assert img.ndim == (2 if enc in ("mono8", "mono16") else 3)


@pytest.fixture(scope="module")
def small_bags(synthetic, tmp_path_factory):
    run, images = synthetic
    d = tmp_path_factory.mktemp("bags")
    write_ros1(d / "small.bag", _messages(run, images, False, True, get_typestore(Stores.ROS1_NOETIC), root="", n=6))
    write_ros2(d / "small_mcap", _messages(run, images, False, False, get_typestore(Stores.ROS2_HUMBLE), root="", n=6),
               StoragePlugin.MCAP)
    return d


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(["ros1", "mcap"]), cut=st.floats(0.0, 0.999), flip=st.integers(0, 2**16))
def test_a_damaged_bag_is_a_typed_error_never_a_crash(small_bags, tmp_path_factory, kind, cut, flip):
    """Truncated or bit-flipped bags replay, or raise CorruptFileError / InvalidInputError."""
    d = tmp_path_factory.mktemp("damaged")
    if kind == "ros1":
        data = bytearray((small_bags / "small.bag").read_bytes())
        target = d / "small.bag"
    else:
        src = small_bags / "small_mcap"
        (d / "b").mkdir()
        for f in src.iterdir():
            (d / "b" / f.name).write_bytes(f.read_bytes())
        target = next((d / "b").glob("*.mcap"))
        data = bytearray(target.read_bytes())
    data = data[: max(1, int(len(data) * (1 - cut)))] if cut > 0.5 else data
    if cut <= 0.5 and data:
        data[flip % len(data)] ^= 0xFF
    target.write_bytes(bytes(data))
    try:
        res = replay(target if kind == "ros1" else d / "b", _config())
    except (CorruptFileError, InvalidInputError):
        return
    assert res.n_odometry >= 2 and np.all(np.diff(res.stamp_ns) > 0)


@pytest.mark.parametrize("field", ["name", "type"])
def test_a_metadata_yaml_with_a_non_string_topic_is_a_corrupt_file(small_bags, tmp_path, field):
    """A ROS2 metadata.yaml whose topic name (or type) is a number raised TypeError (issue 25)."""
    import re

    (tmp_path / "b").mkdir()
    for f in (small_bags / "small_mcap").iterdir():
        (tmp_path / "b" / f.name).write_bytes(f.read_bytes())
    meta = tmp_path / "b" / "metadata.yaml"
    text = meta.read_text()
    edited = re.sub(rf"(\n\s+{field}: )[^\n]+", r"\g<1>42", text, count=1)
    assert edited != text
    meta.write_text(edited)
    with pytest.raises((CorruptFileError, InvalidInputError)):
        replay(tmp_path / "b", _config())


def test_a_config_files_unused_keys_are_one_warning_and_replay_does_not_call_topic_root_unused(config_file):
    """The model warned once per key, topic_root included although the replay reads it (a user's pass, session 47)."""
    from cansim.tools.bag_replay import _load_config

    with pytest.warns(UserWarning) as record:
        cfg, root = _load_config(config_file)
    assert root == "irat_red" and cfg.cell_size_m == 0.1
    assert len(record) == 1 and "'enable' (line 13)" in str(record[0].message)  # the lines as in the file
    assert "[draw]" in str(record[0].message) and "topic_root" not in str(record[0].message)
    with pytest.warns(UserWarning, match=r"'topic_root' \(line 2 - the bag's topics, read by cansim replay\)"):
        RatSLAMConfig.from_file(config_file)  # the model alone: it does not read topic_root, replay does
    with pytest.raises(ConfigError, match="line 5"):  # a malformed value keeps its line number in the replay too
        _load_config(_write(config_file, CFG_TEXT.replace("pc_cell_x_size = 0.1", "pc_cell_x_size = abc")))


def _write(path, text):
    path.write_text(text)
    return path


def test_replay_openratslam_reads_the_file_into_the_cpp_preset(synthetic, config_file, tmp_path):
    """``cansim replay --openratslam``: the file's values in RatSLAMConfig.openratslam (the C++ core bit for bit);
    a config file alone gave the generic engine, with nothing saying so (a user's pass, session 47)."""
    run, images = synthetic
    bag = tmp_path / "run.bag"
    write_ros1(bag, _messages(run, images, False, True, get_typestore(Stores.ROS1_NOETIC)))
    wide = _write(config_file, CFG_TEXT.replace("pc_cell_x_size = 0.1", "pc_cell_x_size = 0.2"))  # <= a cell a step
    with pytest.warns(UserWarning):  # the file's [draw] key
        result = replay(bag, wide, openratslam=True)
    assert result.slam.config.pose_cells == "openratslam" and result.slam.config.cell_size_m == 0.2
    want_cfg = RatSLAMConfig.openratslam(cell_size_m=0.2, frontend=_config().frontend)
    assert_same_map(result.slam, direct(run, images, want_cfg))
    with pytest.warns(UserWarning):
        assert replay(bag, config_file).slam.config.pose_cells == "population"  # the default, as documented
    with pytest.raises(ConfigError, match="applies to a config file"):
        replay(bag, _config(), openratslam=True)
