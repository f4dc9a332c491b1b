"""The JSON Schemas: valid Draft 2020-12, published at schemas/ and reachable where a wheel
ships them (usdmotion/_shipped/schemas), the shipped examples validate; invalid documents
are rejected with the JSON path."""

from __future__ import annotations

import json
from pathlib import Path

import jsonschema
import pytest

from usdmotion.errors import InputError
from usdmotion.schemas import SCHEMA_NAMES, parse_text, schema, validate
from usdmotion.skeleton_names import RIGS_FOLDER, rig_profiles
from usdmotion.synthesis import example_path

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", SCHEMA_NAMES)
def test_schema_is_valid_and_published_at_top_level(name):
    jsonschema.Draft202012Validator.check_schema(schema(name))
    top = REPO / "schemas" / f"{name}.schema.json"
    assert json.loads(top.read_text()) == schema(name)
    shipped = REPO / "usdmotion" / "_shipped" / "schemas" / f"{name}.schema.json"
    assert json.loads(shipped.read_text()) == schema(name)


def test_shipped_examples_validate():
    examples = example_path("giant_swing").parent
    for name, schema_name in (("giant_swing.json", "synthesis"), ("giant_swing_limits.json", "limits")):
        document = json.loads((examples / name).read_text())
        assert validate(document, schema_name, name) is document  # raises InputError if invalid


@pytest.mark.parametrize("path", sorted(RIGS_FOLDER.glob("*.json")), ids=lambda p: p.stem)
def test_shipped_rig_profiles_validate(path):
    # rig_profiles() reads them without jsonschema (start-up); this is their check
    document = json.loads(path.read_text("utf-8"))
    assert validate(document, "rigprofile", path.name) is document
    assert rig_profiles()[document["name"]] == document


@pytest.mark.parametrize("name, document, message", [
    ("body-segments", {"landmarks": {"left_kne": "X"}}, r"/landmarks: 'left_kne' is not one of"),
    ("body-segments", {"segments": [{"name": "a", "from": "A", "to": "B", "mass_fraction": 0, "com_fraction": 0.5}]},
     r"/segments/0/mass_fraction: 0 is less than or equal to the minimum of 0"),
    ("limits", {"joints": {"A": {"x": [0, "90"]}}}, r"/joints/A/x/1: '90' is not of type 'number', 'null'"),
    ("synthesis", {"fps": 30, "joints": [{"name": "A"}], "units": "furlong"}, r"/units: 'furlong' is not valid"),
    ("limits", {"joints": {"A": {"max_speed": float("inf")}}}, r"/joints/A/max_speed: inf is not a finite number"),
])
def test_invalid_documents_name_the_path(name, document, message):
    with pytest.raises(InputError, match=message):
        validate(document, name, "doc.json")


def test_yaml_syntax_errors_have_a_line():
    with pytest.raises(InputError, match=r"doc\.yaml:2: not valid YAML: mapping values are not allowed here"):
        parse_text("fps: 30\njoints: a: b\n", "doc.yaml", "yaml")
