"""Every registered method fills the contract declared on :class:`prtbench.api.method.Method`."""

from __future__ import annotations

import dataclasses

import pytest

from prtbench.api.method import LIGHT_DEPENDENCES, METHODS, STORAGES, Method
from prtbench.scene.model import VARIANTS
from prtbench.scene.registry import SCENES

#: What the harness reads from a method class; each must be declared on the base class.
DECLARED = ("name", "Config", "precompute_version", "profile_overrides", "summary", "paper",
            "light_dependence", "light_dependence_why", "fixed_view", "views_in_key",
            "light_baking_knobs", "storage", "main_knobs", "glossy_only", "regression_case",
            "regression_variants", "no_visibility_reason", "family", "engine_baseline", "verdict_grid")
HOOKS = ("make_config", "cache_identity", "validate", "validate_resolution",
         "compress_dimension", "precompute", "renderer", "op_counts")


def test_the_base_class_declares_the_whole_contract():
    annotations = {k for c in Method.__mro__ for k in getattr(c, "__annotations__", {})}
    for name in DECLARED:
        assert name in annotations, name
    for name in HOOKS:
        assert callable(getattr(Method, name)) and getattr(Method, name).__doc__, name


@pytest.mark.parametrize("name", METHODS.names())
def test_each_method_declares_what_drivers_read(name):
    cls = METHODS.get(name)
    assert cls.name == name and cls.summary and cls.paper
    assert cls.storage in STORAGES, f"{name}: storage {cls.storage!r}"
    assert cls.light_dependence in LIGHT_DEPENDENCES
    assert cls.family, f"{name}: no family (prtbench verdict compares families)"
    assert isinstance(cls.engine_baseline, bool)
    knobs = {f.name for f in dataclasses.fields(cls.Config)}
    for knob, values in (cls.verdict_grid or {}).items():  # prtbench verdict's cells
        assert knob in knobs and (values in ("auto", "auto2") and knob == "texture_resolution"
                                  or values == "@light"
                                  or isinstance(values, list) and values), (name, knob)
    assert set(cls.main_knobs) <= knobs, f"{name}: main_knobs {cls.main_knobs} not all knobs"
    case = dict(cls.regression_case)
    assert set(case) <= {"scene", "variant", "light", "scene_params", "overrides"}, name
    if "scene" in case:
        SCENES.check(case["scene"])
    assert case.get("variant", "diffuse") in VARIANTS
    assert set(case.get("overrides", {})) <= knobs
    for overrides in cls.regression_variants.values():
        assert set(overrides) <= knobs
    cls.make_config(profile="smoke")  # the profile overrides are valid knobs
