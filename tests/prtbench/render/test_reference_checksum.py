"""Cached references are checksummed with their metadata: an edited entry is re-rendered."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.io import imageio
from prtbench.render import reference
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light

ARGS = dict(width=12, height=8, spp=8, seed=3)


@pytest.fixture()
def cached(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    view = scene.trajectory.views[0]
    light = get_light("sky")
    first = reference.render_reference(scene, light, view, **ARGS)
    assert not first.cache_hit
    return scene, light, view, first


def _rewrite(path, image, meta):
    imageio.write_exr(path, image, metadata=meta)


def test_checksum_is_stored_and_verified(cached):
    scene, light, view, first = cached
    meta = imageio.read_exr_metadata(first.path)
    assert meta[reference.CHECKSUM_KEY] == reference.reference_checksum(first.image, meta)
    again = reference.render_reference(scene, light, view, **ARGS)
    assert again.cache_hit and again.spp == first.spp


@pytest.mark.parametrize("edit", ["spp", "noise_rmse_display", "pixels", "no-checksum"])
def test_edited_entry_is_rerendered_and_said_on_stderr(cached, capsys, edit):
    scene, light, view, first = cached
    meta = imageio.read_exr_metadata(first.path)
    image = imageio.read_exr(first.path)
    if edit == "spp":
        meta["spp"] = "4096"  # would be stored as the reference's spp if trusted
    elif edit == "noise_rmse_display":
        meta["noise_rmse_display"] = "1e-09"  # would lift the PSNR ceiling
    elif edit == "pixels":
        image = image.copy()
        lit = np.argwhere(image.max(axis=-1) > 0)[0]
        image[tuple(lit)] *= 1.5  # one geometry pixel
    else:
        del meta[reference.CHECKSUM_KEY]
    _rewrite(first.path, image, meta)
    capsys.readouterr()

    second = reference.render_reference(scene, light, view, **ARGS)
    err = capsys.readouterr().err
    assert not second.cache_hit
    assert "not usable" in err and first.path.name in err and "rendering it again" in err
    assert err.count(first.path.name) == 1, err  # said once, not once per handler
    if edit == "no-checksum":
        assert "older prtbench" in err
    else:
        assert "checksum of pixels and metadata does not match" in err
    # The same seeds render the same reference, with its true metadata, and store it again.
    assert second.spp == 8 and second.noise_rmse_display == first.noise_rmse_display
    assert np.allclose(second.image, first.image, atol=1e-6)
    stored = imageio.read_exr_metadata(second.path)
    assert stored["spp"] == "8"
    assert reference.render_reference(scene, light, view, **ARGS).cache_hit
