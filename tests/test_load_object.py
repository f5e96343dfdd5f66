"""The user's own meshes: whisker_io.sim.objects.load_object and resolve_object.

Expected positions are worked out by hand in each test (the rotation that takes
the file's up axis to +z, the scale, the shift onto z = 0 and the centring), never
by the functions under test.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial import cKDTree

from whisker_io.errors import CansimError, CorruptFileError, InvalidInputError
from whisker_io.sim.catalogue import resolve_object
from whisker_io.sim.objects import (
    MESH_SUFFIXES,
    OBJECT_NAMES,
    LoadedObject,
    load_object,
    make_object,
)

FORMATS = ("obj", "stl", "ply", "glb")


def _pyramid_mm_y_up() -> trimesh.Trimesh:
    """A square pyramid in millimetres, y up: base corners (+-50, 0, +-50), apex (0, 300, 80)
    (leaning toward +z). Its volume is 100 * 100 * 300 / 3 mm^3 = 0.001 m^3."""
    points = [[50, 0, 50], [50, 0, -50], [-50, 0, 50], [-50, 0, -50], [0, 300, 80]]
    return trimesh.convex.convex_hull(np.array(points, dtype=float))


# By hand, for up_axis="y" and scale_to_m=0.3: the quarter turn about x takes (x, y, z) to
# (x, -z, y), so the apex goes to (0, -80, 300) mm and the base corners to (+-50, -+50, 0).
# Extents: x 100, y 130 (-80 .. 50), z 300 -> scale 0.3 / 300 = 0.001. Centring shifts y by
# +15 mm: apex (0, -65, 300) mm; base corners (+-50, -35, 0) for z = +50, (+-50, 65, 0) for z = -50.
PYRAMID_EXPECTED_M = np.array(
    [[0.05, -0.035, 0.0], [-0.05, -0.035, 0.0], [0.05, 0.065, 0.0], [-0.05, 0.065, 0.0], [0.0, -0.065, 0.3]]
)


def _sorted_rows(points) -> np.ndarray:
    points = np.round(np.asarray(points, dtype=float), 12)
    return points[np.lexsort(points.T[::-1])]


def _assert_conventions(obj: LoadedObject) -> None:
    lo, hi = obj.mesh.bounds
    assert lo[2] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=1e-9)
    assert 0.01 <= obj.mesh.extents.max() <= 2.0
    assert np.isfinite(obj.mesh.vertices).all()


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_through_files_y_up_in_millimetres(tmp_path, fmt):
    path = tmp_path / f"pyramid.{fmt}"
    _pyramid_mm_y_up().export(path)
    obj = load_object(path, scale_to_m=0.3, up_axis="y")
    np.testing.assert_allclose(_sorted_rows(obj.mesh.vertices), _sorted_rows(PYRAMID_EXPECTED_M), atol=1e-9)
    assert obj.mesh.is_watertight
    assert obj.mesh.volume == pytest.approx(0.001, rel=1e-9)  # outward normals, right size
    assert obj.scale_factor == pytest.approx(0.001, rel=1e-12)
    assert obj.name == "pyramid" and obj.source == str(path) and obj.up_axis == "+y"
    np.testing.assert_allclose(obj.source_extents, [100.0, 300.0, 130.0])
    assert any("rotated" in n for n in obj.notes) and any("scaled by 0.001" in n for n in obj.notes)
    _assert_conventions(obj)


@pytest.mark.parametrize("fmt", FORMATS)
def test_box_of_known_extents_written_y_up(tmp_path, fmt):
    """A 100 x 350 x 200 mm box (height along y) becomes 0.10 x 0.20 x 0.35 m, z up."""
    path = tmp_path / f"brick.{fmt}"
    trimesh.creation.box(extents=(100.0, 350.0, 200.0), transform=trimesh.transformations.translation_matrix((7, 8, 9))).export(path)
    obj = load_object(path, scale_to_m=0.35, up_axis="Y")
    np.testing.assert_allclose(obj.mesh.bounds, [[-0.05, -0.10, 0.0], [0.05, 0.10, 0.35]], atol=1e-12)
    assert obj.mesh.bounds[0, 2] == 0.0


# Each up axis with the coordinates it leads to, by hand (a proper rotation taking that axis to +z).
UP_MAPS = {
    "z": lambda p: p,
    "+z": lambda p: p,
    "-z": lambda p: np.column_stack([p[:, 0], -p[:, 1], -p[:, 2]]),
    "y": lambda p: np.column_stack([p[:, 0], -p[:, 2], p[:, 1]]),
    "-y": lambda p: np.column_stack([p[:, 0], p[:, 2], -p[:, 1]]),
    "x": lambda p: np.column_stack([-p[:, 2], p[:, 1], p[:, 0]]),
    "-x": lambda p: np.column_stack([p[:, 2], p[:, 1], -p[:, 0]]),
}


@pytest.mark.parametrize("up", list(UP_MAPS))
def test_every_up_axis_is_turned_to_z(up):
    """An irregular tetrahedron (metres): the named axis ends up along +z, no mirror image."""
    points = np.array([[0.01, 0.02, 0.03], [0.21, 0.05, -0.02], [0.04, 0.31, 0.01], [-0.03, 0.07, 0.26]])
    tetra = trimesh.convex.convex_hull(points)
    obj = load_object(tetra, up_axis=up)
    mapped = UP_MAPS[up](points)
    lo, hi = mapped.min(axis=0), mapped.max(axis=0)
    expected = mapped - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]
    np.testing.assert_allclose(_sorted_rows(obj.mesh.vertices), _sorted_rows(expected), atol=1e-12)
    assert obj.mesh.volume == pytest.approx(tetra.volume, rel=1e-9)  # a rotation keeps the volume's sign
    np.testing.assert_allclose(np.linalg.det(obj.rotation), 1.0)
    # the input's highest point along the up axis is the output's highest point
    sign, axis = (-1.0 if up.startswith("-") else 1.0), "xyz".index(up[-1])
    highest = int(np.argmax(sign * points[:, axis]))
    assert expected[highest][2] == pytest.approx(obj.mesh.bounds[1, 2])


def test_transform_maps_input_onto_output_and_input_is_untouched():
    tetra = trimesh.convex.convex_hull(np.array([[0, 0, 0], [2.0, 0, 0], [0, 3.0, 0], [0, 0, 1.0]]))
    before = tetra.vertices.copy()
    obj = load_object(tetra, up_axis="-x", scale_to_m=0.3, name="t")
    np.testing.assert_array_equal(tetra.vertices, before)
    mapped = (obj.transform @ np.column_stack([before, np.ones(len(before))]).T).T[:, :3]
    np.testing.assert_allclose(_sorted_rows(mapped), _sorted_rows(obj.mesh.vertices), atol=1e-12)
    # by hand: -x up takes (x, y, z) to (z, y, -x); extents (1, 3, 2) -> scale 0.3 / 3 = 0.1
    assert obj.scale_factor == pytest.approx(0.1)
    np.testing.assert_allclose(obj.mesh.extents, [0.1, 0.3, 0.2], atol=1e-12)
    assert not obj.rotation.flags.writeable


def test_scene_meshes_are_concatenated():
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), transform=trimesh.transformations.translation_matrix((0.5, 0, 0)))
    scene.add_geometry(trimesh.creation.box(extents=(0.1, 0.1, 0.2)))
    obj = load_object(scene)
    # by hand: x from -0.05 to 0.55, y +-0.05, z from -0.1 to 0.1 -> 0.6 x 0.1 x 0.2, on z = 0
    np.testing.assert_allclose(obj.mesh.bounds, [[-0.3, -0.05, 0.0], [0.3, 0.05, 0.2]], atol=1e-12)
    assert any("concatenated the 2 meshes" in n for n in obj.notes)


def test_glb_scene_with_two_nodes(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), transform=trimesh.transformations.translation_matrix((0, 0.3, 0)))
    scene.add_geometry(trimesh.creation.icosphere(radius=0.05))
    path = tmp_path / "two.glb"
    scene.export(path)
    obj = load_object(path, up_axis="y")
    # y up: the box sits 0.3 above the sphere; heights 0.05 + 0.3 + 0.05 = 0.4 m
    assert obj.mesh.extents[2] == pytest.approx(0.4, abs=1e-6)
    _assert_conventions(obj)
    assert not any("glTF" in n for n in obj.notes)  # the up axis was given: nothing to warn about


def test_a_gltf_file_read_without_an_up_axis_is_taken_as_z_up_with_a_warning(tmp_path, caplog):
    path = tmp_path / "tower.glb"
    trimesh.creation.box(extents=(0.1, 0.4, 0.1)).export(path)  # tall along y, as a y-up glTF holds it
    with caplog.at_level("WARNING", logger="whisker_io.sim.objects"):
        obj = load_object(path)
    assert obj.up_axis == "+z" and obj.mesh.extents[2] == pytest.approx(0.1)  # taken as z-up: lying on its side
    assert [r.levelname for r in caplog.records] == ["WARNING"] and "--up-axis y" in caplog.records[0].getMessage()
    assert any("y-up by their specification" in n for n in obj.notes)
    caplog.clear()
    with caplog.at_level("WARNING", logger="whisker_io.sim.objects"):
        assert not any("glTF" in n for n in load_object(path, up_axis="z").notes)
    assert not caplog.records  # z given explicitly: the user said so
    obj_stl = tmp_path / "tower.stl"
    trimesh.creation.box(extents=(0.1, 0.4, 0.1)).export(obj_stl)
    with caplog.at_level("WARNING", logger="whisker_io.sim.objects"):
        load_object(obj_stl)
    assert not caplog.records  # other formats have no up-axis convention


def test_clean_ups_are_recorded():
    pyramid = trimesh.convex.convex_hull(np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.2, 0], [0.2, 0.2, 0], [0.1, 0.1, 0.3]]))
    inverted = trimesh.Trimesh(pyramid.vertices, pyramid.faces[:, ::-1], process=False)
    assert inverted.volume < 0
    obj = load_object(inverted)
    # by hand: a square pyramid of base 0.2 x 0.2 m and height 0.3 m, 6 triangles all inverted
    assert obj.mesh.volume == pytest.approx(0.2 * 0.2 * 0.3 / 3) and "turned the normals of 6 faces outward" in obj.notes
    assert not any("normals" in n for n in load_object(pyramid).notes)
    extra = trimesh.Trimesh(pyramid.vertices, np.vstack([pyramid.faces, [[0, 0, 1]]]), process=False)
    obj = load_object(extra)
    assert "removed 1 zero-area faces" in obj.notes and len(obj.mesh.faces) == len(pyramid.faces)
    open_box = trimesh.creation.box(extents=(0.3, 0.3, 0.1))
    open_box.update_faces(np.arange(len(open_box.faces)) > 0)  # one triangle of the lid gone: open, still a volume's shell
    assert any("not watertight" in n for n in load_object(open_box).notes)


def test_what_was_assumed_and_the_move_onto_the_table_are_recorded():
    """Units and up axis not given are said to be assumed; a move of the file's frame of a millimetre or more is
    given in metres (the placement, by hand: centred in x and y, the lowest point on z = 0)."""
    far = trimesh.creation.box(extents=(0.2, 0.3, 0.35))
    far.apply_translation((100.0, -50.0, 20.0))  # the box spans z 19.825 .. 20.175
    notes = load_object(far).notes
    assert ("assumed in metres and z up (not checked; otherwise give scale_to_m (--scale-to-m) / up_axis (--up-axis))"
            in notes)
    assert "moved by (-100, 50, -19.82) m to stand centred on z = 0" in notes
    given = load_object(far, scale_to_m=0.35, up_axis="z").notes
    assert not any(n.startswith("assumed") for n in given)
    assert load_object(far, up_axis="z").notes[0] == "assumed in metres (not checked; otherwise give scale_to_m (--scale-to-m))"
    placed = trimesh.creation.box(extents=(0.2, 0.3, 0.35))
    placed.apply_translation((0.0, 0.0, 0.175 + 0.0004))  # 0.4 mm above the table: under the note's millimetre
    assert not any(n.startswith("moved by") for n in load_object(placed).notes)
    centred = trimesh.creation.box(extents=(0.2, 0.3, 0.35))  # centred on the origin: moved up only, no "-0"
    assert "moved by (0, 0, 0.175) m to stand centred on z = 0" in load_object(centred).notes
    off = centred.copy()
    v = off.vertices.copy()
    v[v[:, 0] > 0, 0] = np.nextafter(0.1, 1.0)  # centred but for the last bit: a 7e-18-m move, said as 0
    off.vertices = v
    assert -(off.bounds[0, 0] + off.bounds[1, 0]) / 2 != 0.0
    assert "moved by (0, 0, 0.175) m to stand centred on z = 0" in load_object(off).notes


def test_a_gltf_file_without_options_is_warned_of_its_up_axis_and_said_to_be_taken_as_metres(tmp_path):
    path = tmp_path / "box.glb"
    trimesh.creation.box(extents=(0.2, 0.3, 0.35)).export(path)
    notes = load_object(path).notes
    assert any("y-up by their specification" in n for n in notes)
    assert "assumed in metres (not checked; otherwise give scale_to_m (--scale-to-m))" in notes  # z up: the warning


def _write(tmp_path: Path, name: str, content: str | bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    return path


MALFORMED = [
    ("missing.obj", None, InvalidInputError, "no mesh file"),
    ("empty.obj", "", InvalidInputError, "no triangles"),
    ("empty.stl", "", InvalidInputError, "no triangles"),
    ("text.stl", "hello, not a mesh\n", InvalidInputError, r"no triangles: .*or its content is not STL \(check its format"),
    ("points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", InvalidInputError, "no triangles"),
    ("nan.obj", "v 0 0 nan\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n", InvalidInputError, "NaN/inf"),
    ("inf.obj", "v 0 0 inf\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n", InvalidInputError, "NaN/inf"),
    ("line.obj", "v 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nf 1 2 3\n", InvalidInputError, "no face with non-zero area"),
    ("point.obj", "v 0.1 0.1 0.1\nv 0.1 0.1 0.1\nv 0.1 0.1 0.1\nf 1 2 3\n", InvalidInputError, "single point"),
    ("sheet.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n", InvalidInputError, r"sheet\.obj is flat: 0 m thick.*extrude"),
    ("huge.obj", "v 0 0 0\nv 1e12 0 0\nv 0 1 0\nf 1 2 3\n", InvalidInputError, "no sensible unit"),
    ("notes.txt", "v 0 0 0\n", InvalidInputError, "cannot read"),
    ("garbage.ply", "ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n", CorruptFileError, "not a readable PLY"),
    ("garbage.glb", b"glTF" + bytes(30), CorruptFileError, "not a readable GLB"),
    ("empty.glb", b"", CorruptFileError, "not a readable GLB"),
]


@pytest.mark.parametrize("name,content,error,message", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_files_raise_typed_errors(tmp_path, name, content, error, message):
    path = tmp_path / name if content is None else _write(tmp_path, name, content)
    with pytest.raises(error, match=message) as info:
        load_object(path)
    if error is CorruptFileError:
        assert info.value.path == str(path)


@pytest.mark.parametrize("thickness_m,ok", [(0.0, False), (0.0009, False), (0.001, True), (0.02, True)])
def test_a_sheet_thinner_than_a_millimetre_is_refused(thickness_m, ok):
    plate = trimesh.creation.box(extents=(0.3, 0.2, 1.0))
    plate.vertices[:, 2] *= thickness_m  # 0: every vertex at z = 0, a flat sheet of triangles
    tilted = plate.copy()
    tilted.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 4, [1, 0, 0]))  # its box is not flat
    if ok:
        assert load_object(plate).extents_m.min() == pytest.approx(thickness_m)
        load_object(tilted)
    else:
        for sheet in (plate, tilted):
            with pytest.raises(InvalidInputError, match="is flat.*1 mm thick"):
                load_object(sheet)


def test_a_directory_is_not_a_mesh(tmp_path):
    (tmp_path / "folder.obj").mkdir()
    with pytest.raises(InvalidInputError, match="no mesh file"):
        load_object(tmp_path / "folder.obj")


def test_absurd_sizes_say_what_to_pass():
    with pytest.raises(InvalidInputError, match=r"0\.005 m across.*scale_to_m=0\.35"):
        load_object(trimesh.creation.box(extents=(0.005, 0.005, 0.005)))
    with pytest.raises(InvalidInputError, match=r"350 m across.*millimetres it is 0\.35 m across: pass scale_to_m=0\.35 "
                                                r"\(--scale-to-m 0\.35 on the command line\)$"):
        load_object(trimesh.creation.box(extents=(100.0, 200.0, 350.0)))  # the thesis' size already: said once
    with pytest.raises(InvalidInputError, match=r"500 m across.*pass scale_to_m=0\.5 \(--scale-to-m 0\.5 on the "
                                                r"command line\), or 0\.35 for the thesis objects' size"):
        load_object(trimesh.creation.box(extents=(100.0, 200.0, 500.0)))
    assert load_object(trimesh.creation.box(extents=(100.0, 200.0, 350.0)), scale_to_m=0.35).mesh.extents.max() == pytest.approx(0.35)


def test_faces_naming_no_vertex():
    mesh = trimesh.Trimesh(np.array([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], float), np.array([[0, 1, 2]]), process=False)
    mesh._data["faces"] = np.array([[0, 1, 7]])  # what a broken exporter leaves behind
    with pytest.raises(InvalidInputError, match="name no vertex"):
        load_object(mesh)


@pytest.mark.parametrize(
    "kwargs,message",
    [
        ({"scale_to_m": float("nan")}, "finite"),
        ({"scale_to_m": -0.3}, "between"),
        ({"scale_to_m": 0.0}, "between"),
        ({"scale_to_m": 50.0}, "between"),
        ({"scale_to_m": "0.3"}, "real numbers"),
        ({"up_axis": "w"}, "up_axis"),
        ({"up_axis": ""}, "up_axis"),
        ({"up_axis": "++z"}, "up_axis"),
        ({"name": ""}, "name"),
        ({"name": 3}, "name"),
    ],
)
def test_bad_arguments(kwargs, message):
    with pytest.raises(InvalidInputError, match=message):
        load_object(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), **kwargs)


@pytest.mark.parametrize("bad", [42, None, np.zeros((3, 3)), b"cube.obj", trimesh.Scene()])
def test_not_a_mesh(bad):
    with pytest.raises(InvalidInputError):
        load_object(bad)


# ---------------------------------------------------------------- resolve_object


def test_resolve_registered_names_unchanged():
    for name in OBJECT_NAMES:
        obj = resolve_object(name)
        np.testing.assert_array_equal(obj.mesh.vertices, make_object(name).vertices)
        assert obj.source == "registered object" and obj.scale_factor == 1.0
    assert resolve_object("Box-Stack").name == "box_stack"


def test_resolve_paths_and_meshes(tmp_path):
    path = tmp_path / "pyramid.stl"
    _pyramid_mm_y_up().export(path)
    for spec in (path, str(path)):
        obj = resolve_object(spec, scale_to_m=0.3, up_axis="y")
        np.testing.assert_allclose(_sorted_rows(obj.mesh.vertices), _sorted_rows(PYRAMID_EXPECTED_M), atol=1e-9)
    with pytest.raises(InvalidInputError, match="no mesh file"):
        resolve_object(str(tmp_path / "nothing.obj"))
    # a name with options goes through load_object: the Box scaled to 0.7 m
    assert resolve_object("box", scale_to_m=0.7).mesh.extents.tolist() == pytest.approx([0.4, 0.4, 0.7])


def test_resolve_unknown_lists_the_choices():
    with pytest.raises(InvalidInputError, match=r"'teapot'.*box, box_stack.*duck.*\.obj"):
        resolve_object("teapot")


# ---------------------------------------------------------------- fuzz: only the project's errors escape

_TETRA = trimesh.convex.convex_hull(np.array([[0, 0, 0], [0.2, 0, 0], [0, 0.3, 0], [0, 0, 0.1]]))


@settings(max_examples=80, deadline=None)
@given(
    scale=st.one_of(
        st.none(),
        st.floats(allow_nan=True, allow_infinity=True),
        st.floats(0.005, 2.5),
        st.integers(-(10**30), 10**30),
        st.text(max_size=4),
        st.booleans(),
    )
)
def test_scale_fuzz(scale):
    ok = scale is None or (
        isinstance(scale, (int, float)) and not isinstance(scale, bool) and np.isfinite(float(scale)) and 0.01 <= scale <= 2.0
    )
    try:
        obj = load_object(_TETRA, scale_to_m=scale)
    except CansimError:
        assert not ok
        return
    assert ok
    assert obj.mesh.extents.max() == pytest.approx(0.3 if scale is None else scale, rel=1e-9)
    _assert_conventions(obj)


VALID_UP = {"x", "y", "z", "+x", "+y", "+z", "-x", "-y", "-z"}


@settings(max_examples=80, deadline=None)
@given(up=st.one_of(st.text(max_size=4), st.sampled_from(sorted(VALID_UP) + ["X", " -Y ", "+Z"]), st.integers(), st.none()))
def test_up_axis_fuzz(up):
    ok = up is None or isinstance(up, str) and up.strip().lower() in VALID_UP  # case and spaces ignored; None: z
    try:
        obj = load_object(_TETRA, up_axis=up)
    except CansimError:
        assert not ok
        return
    assert ok
    _assert_conventions(obj)


def _check_loaded_or_project_error(path: Path) -> None:
    try:
        obj = load_object(path)
    except CansimError:
        return
    _assert_conventions(obj)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(content=st.binary(max_size=600), suffix=st.sampled_from(MESH_SUFFIXES))
def test_garbage_files_fuzz(tmp_path, content, suffix):
    _check_loaded_or_project_error(_write(tmp_path, "fuzz" + suffix, content))


_number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-5, 5)).map(repr)
_obj_line = st.one_of(
    st.tuples(st.just("v"), _number, _number, _number).map(" ".join),
    st.tuples(st.just("f"), st.integers(-4, 8), st.integers(-4, 8), st.integers(-4, 8)).map(lambda t: " ".join(map(str, t))),
    st.text(max_size=8),
)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(lines=st.lists(_obj_line, max_size=12))
def test_obj_like_text_fuzz(tmp_path, lines):
    """Vertex and face lines with any numbers and indices (NaN, inf, 0, negative, out of range)."""
    _check_loaded_or_project_error(_write(tmp_path, "fuzz.obj", "\n".join(lines) + "\n"))


@settings(max_examples=40, deadline=None)
@given(spec=st.one_of(st.text(max_size=16), st.sampled_from(list(OBJECT_NAMES) + ["duck-v2", "x.obj", "teapot"])))
def test_resolve_object_fuzz(spec):
    try:
        obj = resolve_object(spec)
    except CansimError:
        return
    assert isinstance(obj, LoadedObject) and len(obj.mesh.faces) > 0


@pytest.mark.parametrize("fmt", ["obj", "stl"])
def test_registered_object_comes_back_from_a_millimetre_y_up_file(tmp_path, fmt):
    """The Kettle written as a CAD tool would (millimetres, y up) loads back onto itself,
    up to the centring of its bounding box (its spout makes the box off-axis)."""
    kettle = make_object("kettle")
    x, y, z = kettle.vertices.T
    file_mesh = trimesh.Trimesh(1000.0 * np.column_stack([x, z, -y]), kettle.faces, process=False)  # z up -> y up
    path = tmp_path / f"kettle.{fmt}"
    file_mesh.export(path)
    obj = load_object(path, up_axis="y", scale_to_m=float(kettle.extents.max()))
    lo, hi = kettle.bounds
    shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    expected_centres = kettle.triangles_center - shift
    assert len(obj.mesh.faces) == len(kettle.faces)
    # every face where it was (STL keeps float32 millimetres: ~1e-7 m); matched both ways
    tree_out, tree_expected = cKDTree(obj.mesh.triangles_center), cKDTree(expected_centres)
    assert tree_out.query(expected_centres)[0].max() < 1e-6
    assert tree_expected.query(obj.mesh.triangles_center)[0].max() < 1e-6


@settings(max_examples=60, deadline=None)
@given(st.text(max_size=20))
def test_object_file_names_are_safe_stems(name):
    """Only letters, digits, '-' and '_' (never a separator or a dot), never empty; a plain name is kept as it is."""
    from whisker_io.sim.catalogue import object_file_name

    out = object_file_name(name)
    assert out and all(c.isalnum() or c in "-_" for c in out)
    assert object_file_name("/data/my mug.obj") == "my_mug" and object_file_name("box_stack") == "box_stack"


def test_object_file_names_take_their_folder_then_a_number_when_two_would_collide():
    from whisker_io.sim.catalogue import object_file_names

    assert object_file_names(["a/mug.obj", "b/mug.stl", "box"]) == ["a_mug", "b_mug", "box"]
    assert object_file_names(["x/a/mug.obj", "y/a/mug.obj", "box"]) == ["mug_1", "mug_2", "box"]
    assert object_file_names(["box", "/x/my mug.obj"]) == ["box", "my_mug"]
    assert object_file_names([]) == []


def test_a_millimetre_mesh_given_straight_to_the_simulator_is_refused_saying_what_to_do():
    """object_trajectory and WhiskChain take a bare mesh: one in millimetres (1000 x too large) made 9,126 poses."""
    from whisker_io.sim.trajectories import object_trajectory
    from whisker_io.sim.whisk_chain import WhiskChain

    cone_mm = trimesh.creation.cone(radius=120.0, height=300.0)
    for build in (lambda: object_trajectory(cone_mm, "A", n_loops=1), lambda: WhiskChain(cone_mm)):
        with pytest.raises(InvalidInputError, match=r"load_object\) is 300 m across.*millimetres.*scale_to_m=0\.3 "):
            build()
    wall = trimesh.creation.box(extents=(3.0, 0.2, 3.0))  # a scene larger than an object is whisked as before
    assert WhiskChain(wall) is not None
    assert len(object_trajectory(load_object(cone_mm, scale_to_m=0.3).mesh, "A", n_loops=1)) > 10


@pytest.mark.parametrize("size", [float("nan"), float("inf")])
def test_a_non_finite_size_is_called_what_it_is(size):
    from whisker_io.sim.objects import check_extent

    with pytest.raises(InvalidInputError, match="non-finite vertex coordinates") as info:
        check_extent(size, "the mesh")
    assert "scale_to_m" not in str(info.value)  # no scale can repair it


# ------------------------------------------------------------------ files a reviewer downloads (session 50's pass)
def test_a_file_in_centimetres_is_told_the_centimetre_scale_and_a_3_m_one_no_refused_value():
    with pytest.raises(InvalidInputError, match=r"36 m across.*centimetres it is 0\.36 m across: pass scale_to_m=0\.36"):
        load_object(trimesh.creation.box(extents=(16.0, 16.0, 36.0)))  # 0.16 x 0.16 x 0.36 m, written in cm
    with pytest.raises(InvalidInputError) as info:
        load_object(trimesh.creation.box(extents=(1.0, 1.0, 3.0)))  # 3 m: not mm (0.003 m) nor cm (0.03 m)
    message = str(info.value)
    assert "scale_to_m=0.35" in message and "0.003" not in message and "0.03 " not in message
    # every value a hint names is one --scale-to-m takes (0.01-2 m) and gives 5 cm or more
    for extent in (2.5, 6.0, 36.0, 150.0, 360.0, 1999.0, 5000.0):
        with pytest.raises(InvalidInputError) as info:
            load_object(trimesh.creation.box(extents=(extent / 2, extent / 2, extent)))
        for value in [float(v) for v in __import__("re").findall(r"scale_to_m=([0-9.]+)", str(info.value))]:
            assert 0.05 <= value <= 2.0, (extent, str(info.value))


def _spheres(gap_m: float) -> trimesh.Trimesh:
    a = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    b = a.copy()
    b.apply_translation((0.2 + gap_m, 0.0, 0.0))  # surfaces gap_m apart (radius 0.1 each)
    return trimesh.util.concatenate([a, b])


def test_several_bodies_are_named_and_far_apart_ones_warned_of():
    far = load_object(_spheres(1.3))  # 1.3 m between the spheres' boxes, 1.6 m across in all
    (note,) = [n for n in far.notes if "bodies" in n]
    assert note.startswith("2 separate bodies up to 1.3 m apart") and "give one object per file" in note
    near = load_object(_spheres(0.05))  # 5 cm apart, 0.45 m across: one object of two parts
    (note,) = [n for n in near.notes if "bodies" in n]
    assert note == "2 separate bodies, whisked as one object"
    assert not [n for n in load_object(trimesh.creation.icosphere(radius=0.1)).notes if "bodies" in n]


def test_repeated_faces_are_removed_and_the_mesh_is_closed_again():
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.3))
    twice = trimesh.Trimesh(box.vertices, np.vstack([box.faces, box.faces[:5]]), process=False)
    assert not twice.is_watertight
    loaded = load_object(twice)
    assert len(loaded.mesh.faces) == 12 and loaded.mesh.is_watertight
    assert "removed 5 duplicate faces" in loaded.notes


def test_a_folder_another_format_and_a_gltf_without_its_buffer_say_what_to_give(tmp_path):
    (tmp_path / "meshes").mkdir()
    with pytest.raises(InvalidInputError, match=r"is a folder; give one mesh file \(\.obj"):
        resolve_object(str(tmp_path / "meshes"))
    off = tmp_path / "cube.off"
    off.write_text("OFF\n")
    with pytest.raises(InvalidInputError, match=r"cube\.off: \.off is not a mesh format read here; convert it"):
        resolve_object(str(off))
    lone = tmp_path / "lone"
    lone.mkdir()
    trimesh.creation.box(extents=(0.2, 0.2, 0.3)).export(tmp_path / "cube.gltf")
    # an exporter's .gltf names its buffer file; copied alone, the buffer is missing
    (lone / "cube.gltf").write_bytes((tmp_path / "cube.gltf").read_bytes())
    buffers = [p.name for p in tmp_path.iterdir() if p.suffix == ".bin"]
    if not buffers:
        pytest.skip("this trimesh writes the buffer inside the .gltf")
    with pytest.raises(CorruptFileError, match=r"cube\.gltf needs (\S+), which is not beside it; copy the files") as info:
        load_object(lone / "cube.gltf")
    assert __import__("re").search(r"needs (\S+), which", str(info.value)).group(1) in buffers


def test_a_flat_file_far_from_the_origin_is_told_to_re_export_centred():
    sheet = trimesh.creation.box(extents=(0.3, 0.3, 1e-6))
    sheet.apply_translation((4.5e5, 5.4e6, 0.0))  # map coordinates, as a single-precision file leaves them
    with pytest.raises(InvalidInputError, match=r"is flat.*coordinates reach 5\.4e\+06.*re-export it centred"):
        load_object(sheet)
    with pytest.raises(InvalidInputError) as info:
        load_object(trimesh.creation.box(extents=(0.3, 0.3, 1e-6)))  # at the origin: no such advice
    assert "re-export it centred" not in str(info.value)


def test_one_bad_vertex_is_one_vertex():
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.3))
    v = box.vertices.copy()
    v[3, 1] = np.nan
    with pytest.raises(InvalidInputError, match=r"has 1 vertex with NaN/inf coordinates \(first: index 3\)"):
        load_object(trimesh.Trimesh(v, box.faces, process=False))
    v[5, 0] = np.inf
    with pytest.raises(InvalidInputError, match=r"has 2 vertices with NaN/inf"):
        load_object(trimesh.Trimesh(v, box.faces, process=False))


def test_two_objects_of_several_parts_far_apart_are_warned_of_and_stray_vertices_are_no_body():
    # each side is two touching boxes: every body's nearest neighbour is beside it, yet the halves are 1.2 m apart
    def pair(x):
        a, b = trimesh.creation.box(extents=(0.1, 0.1, 0.2)), trimesh.creation.box(extents=(0.1, 0.1, 0.2))
        a.apply_translation((x, 0.0, 0.1))
        b.apply_translation((x + 0.11, 0.0, 0.1))
        return [a, b]
    two = load_object(trimesh.util.concatenate([*pair(0.0), *pair(1.41)]))
    (note,) = [n for n in two.notes if "bodies" in n]
    assert note.startswith("4 separate bodies up to 1.2 m apart"), note
    box = trimesh.creation.box(extents=(0.2, 0.2, 0.3))
    stray = np.vstack([box.vertices, [[0.05, 0.05, 0.05], [0.0, 0.0, 0.02]]])  # vertices no face uses
    assert not [n for n in load_object(trimesh.Trimesh(stray, box.faces, process=False)).notes if "bodies" in n]
