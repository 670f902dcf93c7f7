"""The documentation of every study key lives in the pydantic models (``Field(description=...)``);
the JSON Schema and :data:`parasynth.study.spec.KEY_DOCS` are generated from them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from parasynth.study import spec
from parasynth.study.spec import (KEY_DOCS, REFERENCE_KEYS, ConstraintRef, EvaluationSpec, MeasureRef, OptimizerSpec,
                                  PolishSpec, RobustSpec, StructureSpec, StudySpec, VariableSpec, study_json_schema, study_keys)

ROOT = Path(__file__).resolve().parents[2]
MODELS = {"": StudySpec, "variables[].": VariableSpec, "objectives[].": MeasureRef, "constraints[].": ConstraintRef,
          "evaluation.": EvaluationSpec, "optimizer.": OptimizerSpec, "optimizer.polish.": PolishSpec,
          "structure.": StructureSpec, "objectives[].robust.": RobustSpec, "constraints[].robust.": RobustSpec}


@pytest.mark.parametrize("prefix", sorted(MODELS))
def test_every_field_of_the_study_models_has_a_description(prefix):
    model = MODELS[prefix]
    assert model.model_fields
    for name, field in model.model_fields.items():
        assert isinstance(field.description, str) and len(field.description.split()) >= 3, f"{prefix}{name}"
        assert "See docs" not in field.description


def test_the_json_schema_carries_each_fields_description():
    schema = study_json_schema()
    defs = schema["$defs"]
    nodes = {"": schema, **{p: defs[m.__name__] for p, m in MODELS.items() if p}}
    n = 0
    for prefix, model in MODELS.items():
        props = nodes[prefix]["properties"]
        assert set(props) == set(model.model_fields), prefix
        for name, field in model.model_fields.items():
            assert props[name]["description"] == field.description, f"{prefix}{name}"
            n += 1
    # 65 keys before the robust blocks: objectives[].robust and constraints[].robust, and the
    # six keys of each (tolerances, statistic, level, samples, seed, probability); optimizer.polish
    # and its two keys (method, budget)
    assert n == len(study_keys()) == 85
    assert schema["title"] == "parasynth study"
    assert schema["description"].startswith("A parasynth design study")
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    # what the schema command writes
    text = json.dumps(schema, indent=2)
    for doc in KEY_DOCS.values():
        if not doc.startswith(tuple(REFERENCE_KEYS.values())):
            assert json.dumps(doc) in text


def test_key_docs_come_from_the_models():
    assert set(KEY_DOCS) == set(study_keys()) | {f"reference.{k}" for k in REFERENCE_KEYS}
    assert KEY_DOCS["evaluation.samples"] == EvaluationSpec.model_fields["samples"].description
    assert KEY_DOCS["variables[].low"] == VariableSpec.model_fields["low"].description
    assert KEY_DOCS["reference.label"] == REFERENCE_KEYS["label"]
    # a few texts as they were written before they moved into the models
    assert KEY_DOCS["name"] == ("Study name: letters, digits, '_', '.', '-'; names the run directory runs/<name>/ "
                                "and the report.")
    assert KEY_DOCS["optimizer.n_jobs"] == "Same as optimizer.workers (kept for older study files)."
    assert KEY_DOCS["evaluation.samples"] == f"Workspace samples per design (1 to {spec.MAX_SAMPLES}, default 4096)."
    # no separate table of key texts is left to patch into the schema
    source = Path(spec.__file__).read_text()
    assert "KEY_DOCS = {" not in source and '["description"] =' not in source


def test_study_format_doc_documents_the_reference_keys():
    doc = (ROOT / "docs" / "study-format.md").read_text()
    for k in REFERENCE_KEYS:
        assert f"`reference.{k}`" in doc or f"`{k}`" in doc, k
