"""The closure table of the scene contract: lobes as closures, explicit closures, validation."""

import numpy as np
import pytest

from core.scene import closures as C
from core.scene.contract import Materials, SceneError, _validate_materials

pytestmark = pytest.mark.core


def test_lobes_become_closures_in_order_with_their_weights():
    m = Materials.from_list([{"diffuse": (0.5, 0.4, 0.3)},
                             {"specular": (1, 1, 1), "roughness": 0.3,
                              "transmission": (0.9, 0.9, 0.9), "ior": 1.33}])
    t = m.closure_table()
    assert list(t["kind"]) == [C.CLOSURE_DIFFUSE, C.CLOSURE_GLOSSY, C.CLOSURE_GLASS]
    assert list(t["first"]) == [0, 1] and list(t["count"]) == [1, 2]
    np.testing.assert_allclose(t["weight"][0], (0.5, 0.4, 0.3), rtol=1e-6)
    assert t["params"][1, C.ROUGHNESS] == pytest.approx(0.3)
    assert t["params"][2, C.IOR] == pytest.approx(1.33)
    assert t["params"][2, C.ROUGHNESS] == 0.0


def test_explicit_closures_are_stored_and_mixed_with_lobe_rows():
    m = Materials.from_list([
        {"closures": [{"kind": C.CLOSURE_PRINCIPLED, "params": {"metallic": 1.0}},
                      {"kind": C.CLOSURE_SHEEN, "weight": (0.2, 0.2, 0.2), "texture": -1}]},
        {"diffuse": (0.8, 0.8, 0.8)}])
    assert m.closure_kind is not None
    t = m.closure_table()
    assert list(t["kind"]) == [C.CLOSURE_PRINCIPLED, C.CLOSURE_SHEEN, C.CLOSURE_DIFFUSE]
    assert t["params"][0, C.METALLIC] == 1.0 and t["params"][0, C.ROUGHNESS] == 0.5
    _validate_materials(m, texture_count=0)


def test_unknown_parameter_and_bad_tables_are_named():
    with pytest.raises(KeyError, match="metalic"):
        C.params(metalic=1.0)
    m = Materials.from_list([{"closures": [{"kind": 99}]}])
    with pytest.raises(SceneError, match="closure_kind"):
        _validate_materials(m, texture_count=0)
    m = Materials.from_list([{"closures": [{"kind": C.CLOSURE_DIFFUSE, "texture": 3}]}])
    with pytest.raises(SceneError, match="closure_texture"):
        _validate_materials(m, texture_count=1)
