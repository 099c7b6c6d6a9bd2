"""fluorite: fit the diffuse fluorescent BBRRDF (Jung et al. 2018) to measured
bispectral reradiation matrices, and check, export and render the materials.

Every call goes to the Rust library the ``fluorite`` command line is built on; nothing
is computed again in Python. Arrays are numpy float64; a measurement's ``values`` has
shape ``(n_excitation, n_emission)`` (rows excitation, columns emission, whatever the
file's orientation) and NaN marks a missing cell.

Quick start::

    import fluorite
    fit = fluorite.fit("data/red-pigment.csv")      # or a Measurement
    fit.delta_e                                       # {'a': ..., 'd65': ..., ...}
    fit.material.save("red-pigment.json")             # what `fluorite fit` writes
    m = fluorite.read("HERPICER.BFC")                 # m.excitation, m.emission, m.values
    fluorite.fit_many(["a.BFC", "b.BFC"], threads=2)  # in parallel, GIL released
    linear, srgb = fluorite.render(fit.material, light="d65", spp=16, size=(320, 200))
    image = fluorite.fit_image("scan.exr", output="out/scan")   # or a numpy array (H, W, ex, em)
    image.components, image.map.concentration().shape  # K, (height, width, K)

Errors are ``fluorite.FluoriteError`` (a ``ValueError``) with the command line's
message. The GIL is released during every read, fit, joint fit, image fit and render.
"""

from ._fluorite import (
    DEFAULT_COLOUR_WEIGHT,
    DEFAULT_TOLERANCE,
    STANDARD_LIGHTS,
    WATER_RAMAN_SHIFT_CM,
    Fit,
    Fluorophore,
    FluoriteError,
    ImageFit,
    JointResult,
    Light,
    Material,
    MaterialMap,
    Measurement,
    ParafacFit,
    __version__,
    fit,
    fit_image,
    fit_many,
    joint,
    read,
    render,
    write_image,
)

__all__ = [
    "DEFAULT_COLOUR_WEIGHT",
    "DEFAULT_TOLERANCE",
    "STANDARD_LIGHTS",
    "WATER_RAMAN_SHIFT_CM",
    "Fit",
    "Fluorophore",
    "FluoriteError",
    "ImageFit",
    "JointResult",
    "Light",
    "Material",
    "MaterialMap",
    "Measurement",
    "ParafacFit",
    "__version__",
    "fit",
    "fit_image",
    "fit_many",
    "joint",
    "read",
    "render",
    "write_image",
]
