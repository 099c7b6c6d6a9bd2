"""Rendering: image shapes and types; the furnace agrees with the material's colour.

In the furnace a convex diffuse sphere sits in a uniform environment of the light (unit
luminance), so every point of it returns exactly the flat patch's light: the pixels
inside the sphere, converted from linear sRGB back to XYZ with the inverse of the sRGB
matrix (IEC 61966-2-1), must read ``Material.colour(light)["xyz"] / 100`` up to Monte
Carlo noise (the render is not adapted under D65 either way).
"""

import json
from pathlib import Path

import numpy as np
import pytest

import fluorite

# IEC 61966-2-1: linear sRGB → XYZ (D65).
SRGB_TO_XYZ = np.array(
    [
        [0.4124, 0.3576, 0.1805],
        [0.2126, 0.7152, 0.0722],
        [0.0193, 0.1192, 0.9505],
    ]
)


def plain_material():
    wavelengths = np.arange(380.0, 781.0, 10.0)
    reflectance = 0.2 + 0.6 * np.exp(-(((wavelengths - 600.0) / 60.0) ** 2))
    return fluorite.Material("plain", wavelengths, reflectance)


def test_render_shapes_and_types():
    linear, srgb = fluorite.render(plain_material(), spp=2, size=(24, 16))
    assert linear.shape == (16, 24, 3) and linear.dtype == np.float32
    assert srgb.shape == (16, 24, 3) and srgb.dtype == np.uint8
    assert np.isfinite(linear).all() and linear.max() > 0
    twin, twin8 = fluorite.render(plain_material(), spp=1, size=(40, 20), compare=True, light="a")
    assert twin.shape == (20, 40, 3) and twin8.shape == (20, 40, 3)
    with pytest.raises(fluorite.FluoriteError, match="--spp"):
        fluorite.render(plain_material(), spp=0)
    with pytest.raises(fluorite.FluoriteError, match="scene"):
        fluorite.render(plain_material(), scene="kitchen")


def furnace_xyz(material, light):
    size = 48
    linear, _ = fluorite.render(material, scene="furnace", light=light, spp=128, size=(size, size), seed=7)
    centre = linear[size // 2 - 6 : size // 2 + 6, size // 2 - 6 : size // 2 + 6].reshape(-1, 3)
    return SRGB_TO_XYZ @ centre.mean(axis=0).astype(np.float64)


def test_furnace_of_a_plain_reflector_matches_its_colour():
    material = plain_material()
    xyz = furnace_xyz(material, "d65")
    expected = material.colour("d65")["xyz"] / 100.0
    # Monte Carlo: 144 pixels × 128 paths × 4 wavelengths; the sRGB matrix's four decimals
    # add about 1e-4.
    np.testing.assert_allclose(xyz, expected, rtol=0.02, atol=2e-3)


def test_furnace_of_a_fluorescent_material_matches_its_colour():
    truth = Path(__file__).resolve().parents[2] / "data" / "red-pigment.truth.json"
    material = fluorite.Material.from_json(truth.read_text())
    assert material.fluorophores
    xyz = furnace_xyz(material, "d65")
    expected = material.colour("d65")["xyz"] / 100.0
    np.testing.assert_allclose(xyz, expected, rtol=0.03, atol=3e-3)
