"""The OpenRatSLAM config adapter (cansim.models.openratslam_config) and RatSLAMConfig's one-name-per-concept fields.

Expected values are written by hand from the key table (the module docstring and
docs/concepts/ratslam.rst), never computed by the adapter.
"""

from __future__ import annotations

import dataclasses
import ast
import io
import math
import re
import tokenize
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cansim.models.openratslam_config as adapter
from cansim import RatSLAM, RatSLAMConfig
from cansim.errors import ConfigError
from cansim.frontends.tactile import TactileTemplateConfig
from cansim.frontends.visual import VisualTemplateConfig
from cansim.frontends.whisk import WhiskFrontEndConfig
from cansim.params import AttractorParams
from cansim.models.whisker_ratslam import WhiskerRatSLAMConfig
from maps.experience_map import MapConfig

ROOT = Path(__file__).resolve().parents[1]

# every OpenRatSLAM key with a distinct value, and where it must land (by hand)
ALL_KEYS_TEXT = """# an OpenRatSLAM config with every key cansim reads
[general]
topic_root=irat_red

[ratslam]
pc_dim_xy=23
pc_dim_th=40
pc_cell_x_size=0.35
pc_w_e_dim=9
pc_w_e_var=3
pc_w_i_dim=3
pc_w_i_var=4
pc_global_inhib=0.0001
pc_cells_to_avg=2
pc_vt_inject_energy=0.2
vt_active_decay=0.8
pc_vt_restore=0.07
exp_delta_pc_threshold=1.5
exp_correction=0.25
exp_loops=7
exp_initial_em_deg=45
template_x_size=50
template_y_size=12
image_crop_x_min=4
image_crop_x_max=300
image_crop_y_min=6
image_crop_y_max=200
vt_shift_match=11
vt_step_match=2
vt_match_threshold=0.045
vt_normalisation=0.4
vt_patch_normalise=3
vt_min_patch_normalisation_std=0.01
vt_panoramic=1

[draw]
enable=0
"""

EXPECTED = {
    "pc_dim_xy": ("xy_cells", 23),
    "pc_dim_th": ("heading_cells", 40),
    "pc_cell_x_size": ("cell_size_m", 0.35),
    "pc_w_e_dim": ("attractor.exc_width", 9),
    "pc_w_e_var": ("attractor.exc_sigma", 3.0),
    "pc_w_i_dim": ("attractor.inh_width", 3),
    "pc_w_i_var": ("attractor.inh_sigma", 4.0),
    "pc_global_inhib": ("attractor.global_inhibition", 0.0001),
    "pc_cells_to_avg": ("decode_window", 2),
    "pc_vt_inject_energy": ("inject_energy", 0.2),
    "vt_active_decay": ("active_decay", 0.8),
    "pc_vt_restore": ("decay_restore", 0.07),
    "exp_delta_pc_threshold": ("match_distance_cells", 1.5),
    "exp_correction": ("correction", 0.25),
    "exp_loops": ("relax_passes", 7),
    "exp_initial_em_deg": ("initial_heading_deg", 45.0),
    "template_x_size": ("frontend.template_width_blocks", 50),
    "template_y_size": ("frontend.template_height_blocks", 12),
    "image_crop_x_min": ("frontend.crop_x_min_px", 4),
    "image_crop_x_max": ("frontend.crop_x_max_px", 300),
    "image_crop_y_min": ("frontend.crop_y_min_px", 6),
    "image_crop_y_max": ("frontend.crop_y_max_px", 200),
    "vt_shift_match": ("frontend.shift_match_blocks", 11),
    "vt_step_match": ("frontend.step_match_blocks", 2),
    "vt_match_threshold": ("frontend.match_threshold", 0.045),
    "vt_normalisation": ("frontend.normalisation_mean", 0.4),
    "vt_patch_normalise": ("frontend.patch_half_width_blocks", 3),
    "vt_min_patch_normalisation_std": ("frontend.min_patch_std", 0.01),
    "vt_panoramic": ("frontend.panoramic", True),
}


def _get(cfg, dotted):
    for part in dotted.split("."):
        cfg = getattr(cfg, part)
    return cfg


def _documented_keys(text):
    """The keys in the first column of the reST tables of a text."""
    return set(re.findall(r"^``([a-z_]+)``\s", text, re.M))


def test_every_documented_key_lands_in_its_field(tmp_path):
    path = tmp_path / "config_all.txt.in"
    path.write_text(ALL_KEYS_TEXT)
    with pytest.warns(UserWarning) as record:
        cfg = RatSLAMConfig.from_file(path)
    assert len(record) == 1  # one warning naming every key nothing uses, by section
    assert sorted(re.findall(r"'(\w+)' \(line", str(record[0].message))) == ["enable", "topic_root"]
    assert "2 OpenRatSLAM config keys not used" in str(record[0].message) and "read by cansim replay" in str(record[0].message)
    for key, (field, value) in EXPECTED.items():
        got = _get(cfg, field)
        assert got == value and type(got) is type(value), (key, field, got)
    # the fields no key sets keep their defaults
    assert (cfg.lv_mode, cfg.frame, cfg.relax_budget, cfg.attractor.kernel_normalisation) == ("stored", "standard", 2000, "sum")
    assert cfg.frontend.emulate_uninitialised_clear is False
    # the adapter documents exactly these keys, and its table holds exactly them
    assert _documented_keys(adapter.__doc__) == set(EXPECTED) == set(adapter.OPENRATSLAM_KEYS)


def test_docs_table_documents_the_same_keys():
    text = (ROOT / "docs" / "concepts" / "ratslam.rst").read_text(encoding="utf-8")
    keys = set()
    for first_column in re.findall(r"^(``[a-z_]+``(?:, ``[a-z_]+``)*)\s{2,}", text, re.M):
        keys.update(re.findall(r"``([a-z_]+)``", first_column))
    assert keys == set(EXPECTED)


def test_crop_edge_and_value_spellings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no key here is unknown
        cfg = RatSLAMConfig.from_text("[ratslam]\nimage_crop_x_max=-1\nimage_crop_y_max = -1.0\nvt_panoramic=yes\npc_dim_xy=25.0\n; comment\n")
    assert (cfg.frontend.crop_x_max_px, cfg.frontend.crop_y_max_px, cfg.frontend.panoramic, cfg.xy_cells) == (None, None, True, 25)
    assert RatSLAMConfig.from_text("vt_panoramic=off\n").frontend.panoramic is False
    assert RatSLAMConfig.from_text("").frontend == VisualTemplateConfig()  # an OpenRatSLAM front end is visual


def test_overrides_use_the_new_names_and_win():
    cfg = RatSLAMConfig.from_text("pc_dim_xy=23\nvt_match_threshold=0.045\n", frontend="ids", cell_size_m=0.5)
    assert (cfg.xy_cells, cfg.frontend, cfg.cell_size_m) == (23, "ids", 0.5)
    with pytest.raises(ConfigError, match="pc_dim_th is OpenRatSLAM's name: use heading_cells="):
        RatSLAMConfig.from_text("pc_dim_xy=23\n", pc_dim_th=12)
    with pytest.raises(ConfigError, match=r"RatSLAMConfig has no field .xy_cell. \(did you mean .xy_cells.\?\)"):
        RatSLAMConfig.from_text("", xy_cell=3)


@pytest.mark.parametrize(
    "line,names",
    [
        ("pc_dim_xy=2.5", ("pc_dim_xy", "line 3")),
        ("exp_loops=ten", ("exp_loops", "line 3")),
        ("vt_match_threshold=nan", ("vt_match_threshold", "line 3")),
        ("vt_panoramic=maybe", ("vt_panoramic", "line 3")),
        ("pc_w_e_dim=4", ("pc_w_e_dim (line 3)", "attractor.exc_width", "odd")),
        ("pc_w_i_var=0", ("pc_w_i_var (line 3)", "attractor.inh_sigma")),
        ("exp_correction=1.5", ("exp_correction (line 3)", "correction")),
        ("pc_global_inhib=-1", ("pc_global_inhib (line 3)", "global_inhibition")),
        ("vt_shift_match=30", ("vt_shift_match (line 3)", "shift_match_blocks")),
        ("image_crop_x_max=0", ("image_crop_x_max (line 3)", "crop_x_max_px")),
        ("just text", ("line 3", "key=value")),
    ],
)
def test_bad_value_names_the_key_and_line(line, names):
    with pytest.raises(ConfigError) as info:
        RatSLAMConfig.from_text(f"# header\n[ratslam]\n{line}\n")
    for name in names:
        assert name in str(info.value), str(info.value)


def test_missing_file_is_a_config_error(tmp_path):
    with pytest.raises(ConfigError, match="no such OpenRatSLAM config file"):
        RatSLAMConfig.from_file(tmp_path / "absent.txt.in")


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_openratslam_names_as_keywords_name_the_new_field(key):
    field = EXPECTED[key][0]
    new = field.split(".")[-1]
    for make in (lambda: RatSLAMConfig(**{key: 1}), lambda: RatSLAM(**{key: 1}), lambda: RatSLAMConfig.openratslam(**{key: 1})):
        with pytest.raises(ConfigError) as info:
            make()
        msg = str(info.value)
        assert msg.startswith(f"{key} is OpenRatSLAM's name: use ") and f"{new}=..." in msg
        assert "RatSLAMConfig.from_file reads OpenRatSLAM files" in msg
        if field.startswith("attractor."):
            assert "attractor=AttractorParams(" in msg
        if field.startswith("frontend."):
            assert "frontend=VisualTemplateConfig(" in msg


def test_front_end_is_selected_by_type():
    assert RatSLAM(frontend=TactileTemplateConfig(match_threshold=5.0)).frontend.templates.config.match_threshold == 5.0
    visual = VisualTemplateConfig(template_width_blocks=8, template_height_blocks=2, shift_match_blocks=1)
    assert RatSLAM(frontend=visual).frontend.templates.config is visual
    for bad in ("visual", "tactile", None, 3, AttractorParams()):
        with pytest.raises(ConfigError, match="frontend must be 'ids', a VisualTemplateConfig"):
            RatSLAMConfig(frontend=bad)


@pytest.mark.parametrize("frontend", ["ids", VisualTemplateConfig(crop_x_max_px=100, panoramic=True), TactileTemplateConfig(3.5)])
def test_dict_round_trip(frontend):
    import json

    cfg = RatSLAMConfig(xy_cells=15, attractor=AttractorParams(exc_width=(7, 7, 5)), frontend=frontend)
    back = RatSLAMConfig.from_dict(json.loads(json.dumps(cfg.to_dict())))
    assert back == cfg
    with pytest.raises(ConfigError, match="not a RatSLAMConfig description"):
        RatSLAMConfig.from_dict({**cfg.to_dict(), "frontend": {"kind": "sonar"}})


# ---------------------------------------------------------------- bad configs (hypothesis)
WRONG = st.one_of(st.none(), st.text(max_size=3), st.just(math.nan), st.just(math.inf), st.just(-math.inf), st.booleans(),
                  st.lists(st.integers(), max_size=2))
INT_FIELDS = ["xy_cells", "heading_cells", "decode_window", "relax_passes"]
FLOAT_FIELDS = ["cell_size_m", "inject_energy", "active_decay", "decay_restore", "match_distance_cells", "correction",
                "initial_heading_deg"]


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(INT_FIELDS + FLOAT_FIELDS + ["relax_budget"]), WRONG)
def test_wrong_types_and_non_finite_values_raise_config_error(field, value):
    if field == "relax_budget" and value is None:
        return  # None is the unbounded relaxation
    with pytest.raises(ConfigError, match=re.escape(field)):
        RatSLAMConfig(**{field: value})


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(INT_FIELDS), st.floats(allow_nan=False, allow_infinity=False).filter(lambda x: not x.is_integer()))
def test_fractional_counts_raise_config_error(field, value):
    with pytest.raises(ConfigError, match=field):
        RatSLAMConfig(**{field: value})


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["exc_width", "inh_width"]), st.integers(-20, 20).filter(lambda n: n < 1 or n % 2 == 0), st.booleans())
def test_even_or_non_positive_kernel_widths_raise_config_error(name, width, per_axis):
    value = (7, width, 5) if per_axis else width
    with pytest.raises(ConfigError, match=f"attractor.{name} must be an odd integer >= 1"):
        RatSLAMConfig(attractor=AttractorParams(**{name: value}))


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["exc_sigma", "inh_sigma"]), st.one_of(st.floats(max_value=0), st.just(math.nan), st.just(math.inf)))
def test_bad_kernel_sigmas_raise_config_error(name, sigma):
    with pytest.raises(ConfigError, match=f"attractor.{name}"):
        RatSLAMConfig(attractor=AttractorParams(**{name: sigma}))


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.sampled_from(sorted(EXPECTED)), st.from_regex(r"\A[a-z][a-z_]{0,12}\Z")), st.integers(1, 9))
def test_unknown_and_openratslam_names_raise_config_error(name, value):
    fields = set(RatSLAMConfig.__dataclass_fields__)
    if name in fields:
        return
    with pytest.raises(ConfigError) as info:
        RatSLAMConfig(**{name: value})
    assert ("OpenRatSLAM's name" in str(info.value)) == (name in EXPECTED)


@settings(max_examples=100, deadline=None)
@given(st.sampled_from(["lv_mode", "frame", "dtype", "pose_cells", "backend"]), st.one_of(st.integers(), st.none(), st.sampled_from(["", "x"])))
def test_bad_names_raise_config_error(field, value):
    if field == "backend" and isinstance(value, str):
        return  # any backend name is accepted here; the registry refuses unknown ones when the model is built
    with pytest.raises(ConfigError, match=field):
        RatSLAMConfig(**{field: value})


@settings(max_examples=100, deadline=None)
@given(st.sampled_from([
    (MapConfig, "correction"), (MapConfig, "relax_passes"), (MapConfig, "match_distance_cells"), (MapConfig, "relax_budget"),
    (WhiskFrontEndConfig, "pfh_threshold"), (WhiskFrontEndConfig, "n_bins"), (WhiskFrontEndConfig, "feature_update"),
    (WhiskFrontEndConfig, "features"), (WhiskerRatSLAMConfig, "grid_cells"), (WhiskerRatSLAMConfig, "cell_size_m"),
    (WhiskerRatSLAMConfig, "inject_energy"), (WhiskerRatSLAMConfig, "lv_mode"), (VisualTemplateConfig, "template_width_blocks"),
    (VisualTemplateConfig, "match_threshold"), (VisualTemplateConfig, "panoramic"), (TactileTemplateConfig, "match_threshold"),
]), WRONG)
def test_the_other_configs_share_the_validator(target, value):
    cls, field = target
    if value is None and field == "relax_budget":
        return
    if isinstance(value, bool) and field in ("feature_update", "panoramic"):
        return  # a valid boolean
    with pytest.raises(ConfigError, match=re.escape(field)):
        cls(**{field: value})


# ---------------------------------------------------------------- OpenRatSLAM names live in the adapter only
def _code_words(path):
    """Identifiers, keyword names, string literals that are not docstrings, and comments of a Python file."""
    text = path.read_text(encoding="utf-8")
    tree = ast.parse(text)
    docstrings = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                docstrings.add(id(first.value))
            # the attribute docstring after an assignment ("""...""" under a constant)
            for a, b in zip(node.body, node.body[1:]):
                if isinstance(a, (ast.Assign, ast.AnnAssign)) and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant):
                    docstrings.add(id(b.value))
    words = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            words.append(node.value)
        elif isinstance(node, ast.Name):
            words.append(node.id)
        elif isinstance(node, ast.Attribute):
            words.append(node.attr)
        elif isinstance(node, (ast.keyword, ast.arg)) and node.arg:
            words.append(node.arg)
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            words.append(node.name)
    words += [t.string for t in tokenize.generate_tokens(io.StringIO(text).readline) if t.type == tokenize.COMMENT]
    return words


def _uses_of_keys(path):
    return sorted({key for word in _code_words(path) for key in EXPECTED if key in word})


def test_openratslam_key_names_appear_in_code_only_in_the_adapter():
    sources = [p for d in ("cansim", "maps", "whisker_io", "examples", "bench") for p in sorted((ROOT / d).rglob("*.py"))]
    assert len(sources) > 50
    adapter_path = ROOT / "cansim" / "models" / "openratslam_config.py"
    offenders = {str(p.relative_to(ROOT)): _uses_of_keys(p) for p in sources if p != adapter_path}
    assert {k: v for k, v in offenders.items() if v} == {}
    assert _uses_of_keys(adapter_path) == sorted(EXPECTED)  # the scan sees them where they are


# ------------------------------------------------- saves of the flat config (cansim 0.x)
def test_flat_dict_of_earlier_versions_maps_onto_the_fields():
    from cansim.frontends.tactile import TactileTemplateConfig
    from cansim.models.openratslam_config import config_from_flat_dict

    cfg = config_from_flat_dict({
        "pc_dim_xy": 11, "pc_dim_th": 12, "pc_w_e_dim": 5, "pc_w_e_var": 1.5, "pc_cell_x_size": 0.02,
        "pc_vt_inject_energy": 0.2, "exp_loops": 7, "exp_initial_em_deg": 180.0, "vt_match_threshold": 15.0,
        "image_crop_x_max": -1, "frontend": "tactile", "relax_budget": 300, "lv_mode": "stored",
    }, RatSLAMConfig)
    assert (cfg.xy_cells, cfg.heading_cells, cfg.cell_size_m) == (11, 12, 0.02)
    assert (cfg.attractor.exc_width, cfg.attractor.exc_sigma) == (5, 1.5)
    assert (cfg.inject_energy, cfg.relax_passes, cfg.initial_heading_deg, cfg.relax_budget) == (0.2, 7, 180.0, 300)
    assert cfg.frontend == TactileTemplateConfig(match_threshold=15.0)
    visual = config_from_flat_dict({"pc_dim_xy": 9, "frontend": "visual", "image_crop_x_max": -1, "template_x_size": 80}, RatSLAMConfig)
    assert visual.frontend.crop_x_max_px is None and visual.frontend.template_width_blocks == 80
    with pytest.raises(ConfigError, match="frontend"):
        config_from_flat_dict({"pc_dim_xy": 9, "frontend": "sonar"}, RatSLAMConfig)
    with pytest.raises(ConfigError, match="not_a_key"):
        config_from_flat_dict({"pc_dim_xy": 9, "not_a_key": 1}, RatSLAMConfig)


def test_a_model_saved_by_an_earlier_version_loads_and_continues_as_it_would_have():
    # tests/data/ratslam_0x_tactile.npz and its next state were written by cansim at commit
    # 93c784f (the flat OpenRatSLAM-named config): the thesis Ch.3 preset on a 10 x 10 x 12
    # grid after 12 tactile steps, then one more step with the image stored in the JSON
    import json
    from pathlib import Path

    from cansim import RatSLAM

    data = Path(__file__).parent / "data"
    expected = json.loads((data / "ratslam_0x_tactile_next_state.json").read_text())
    slam = RatSLAM.load(data / "ratslam_0x_tactile.npz")
    assert (slam.config.xy_cells, slam.config.heading_cells, slam.config.cell_size_m) == (10, 12, 0.02)
    s = slam.step(0.01, 0.02, 1.0, np.array(expected["image"], dtype=np.uint8))
    assert list(s.best_pc) == expected["best_pc"] and list(s.map_pose) == expected["map_pose"]
    assert (s.exp_id, s.relocalised, s.view_id) == (expected["exp_id"], expected["relocalised"], expected["view_id"])


# ------------------------------------------------- writing OpenRatSLAM's config
@settings(max_examples=30, deadline=None)
@given(xy=st.integers(3, 61), th=st.integers(4, 72), cell=st.floats(0.01, 2.0, allow_nan=False),
       inject=st.floats(0.0, 1.0), loops=st.integers(0, 50), visual=st.booleans())
def test_written_config_reads_back_to_the_same_keyed_values(xy, th, cell, inject, loops, visual):
    from cansim.models.openratslam_config import OPENRATSLAM_KEYS, read_openratslam_text, write_openratslam_text

    cfg = RatSLAMConfig.openratslam(xy_cells=xy, heading_cells=th, cell_size_m=cell, inject_energy=inject,
                                    relax_passes=loops)
    if visual:
        cfg = dataclasses.replace(cfg, frontend=VisualTemplateConfig(crop_x_max_px=None, panoramic=True))
    text = write_openratslam_text(cfg)
    assert text.startswith("[ratslam]\n") and ("template_x_size=" in text) == visual
    back = read_openratslam_text(text, RatSLAMConfig)
    for key, (field, _) in OPENRATSLAM_KEYS.items():
        part, _, name = field.rpartition(".")
        if part == "frontend" and not visual:
            continue
        got, want = (getattr(getattr(c, part), name) if part else getattr(c, name) for c in (back, cfg))
        assert got == want, key


@settings(max_examples=15, deadline=None)
@given(st.one_of(st.none(), st.just("xy_cells=21"), st.integers(), st.just(VisualTemplateConfig())))
def test_writing_anything_but_a_ratslam_config_raises(config):
    from cansim.models.openratslam_config import write_openratslam_text

    with pytest.raises(ConfigError, match="RatSLAMConfig"):
        write_openratslam_text(config)


def test_unused_keys_are_named_by_the_section_and_the_line_an_editor_shows():
    """A header with a comment ("[draw] ; viewer") was not a header, and a form feed in a comment shifted the
    line numbers by one (str.splitlines splits on it; an editor does not)."""
    text = "[ratslam]\npc_dim_xy=31\n# page\x0cbreak\n[draw] ; the viewer\nenable=1\n"
    with pytest.warns(UserWarning) as record:
        cfg = RatSLAMConfig.from_text(text)
    assert cfg.xy_cells == 31
    assert str(record[0].message).endswith("ignored: [draw] 'enable' (line 5)")
