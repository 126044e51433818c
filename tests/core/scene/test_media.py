"""The media contract (core/scene/media.py): defaults, derived fields, validation messages
naming the field and the medium."""

import numpy as np
import pytest

from core.scene import shapes
from core.scene.contract import SceneError
from core.scene.media import WORLD, Media


def _media(**over):
    rows = [dict(name="Fog", sigma_a=(0.1, 0.1, 0.1), sigma_s=(0.5, 0.4, 0.3), anisotropy=0.3),
            dict(name="Smoke", sigma_s=(2, 2, 2), bounds=0,
                 boundary=shapes.box((0, 0, 0), (1, 1, 1)).corners)]
    rows[1].update(over)
    return Media.from_list(rows)


def test_defaults_and_derived_fields():
    m = _media()
    assert m.count == 2 and m.world == 0
    np.testing.assert_allclose(m.sigma_t[0], [0.6, 0.5, 0.4], rtol=1e-6)
    assert m.bounds.dtype == np.int32 and m.sigma_a.dtype == np.float32
    assert list(m.density_texture) == [-1, -1] and m.emission.sum() == 0
    assert m.boundary.shape == (12, 3, 3) and list(np.unique(m.boundary_medium)) == [1]
    m.validate(object_count=1)
    _media(anisotropy=1.0).validate(object_count=1)  # Blender's range; the kernels clamp
    assert Media.empty().count == 0 and Media.empty().world == -1
    Media.empty().validate(object_count=0)


@pytest.mark.parametrize("over, message", [
    (dict(sigma_s=(1, -1, 1)), "media.sigma_s of 'Smoke' must be >= 0"),
    (dict(anisotropy=-1.5), "media.anisotropy of 'Smoke' must lie in \\[-1, 1\\]"),
    (dict(bounds=3), "media.bounds of 'Smoke' must be an object index in \\[0, 1\\)"),
    (dict(bounds=WORLD), "only one World medium is allowed, got 'Fog', 'Smoke'"),
    (dict(density_texture=0), "media.density_texture of 'Smoke' must be -1"),
    (dict(emission=(np.inf, 0, 0)), "media.emission of 'Smoke' holds a non-finite value"),
])
def test_validation_names_the_field_and_the_medium(over, message):
    with pytest.raises(SceneError, match=message):
        _media(**over).validate(object_count=1)


def test_wrong_dtype_is_reported():
    m = _media()
    bad = Media(m.sigma_a.astype(np.float64), m.sigma_s, m.anisotropy, m.emission, m.bounds,
                m.density_texture, m.names)
    with pytest.raises(SceneError, match="media.sigma_a must be float32, got float64"):
        bad.validate(object_count=1)
