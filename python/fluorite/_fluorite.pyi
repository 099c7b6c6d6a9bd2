"""Typed stubs of the extension module ``fluorite._fluorite`` (re-exported by ``fluorite``).

Array orientation everywhere: a measurement's ``values`` is float64 of shape
``(n_excitation, n_emission)``; NaN marks a missing cell. A bispectral image is
``(height, width, n_excitation, n_emission)``.
"""

import os
from typing import Any, Callable, Dict, Iterable, List, Literal, Optional, Protocol, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str
STANDARD_LIGHTS: List[str]
DEFAULT_TOLERANCE: float
DEFAULT_COLOUR_WEIGHT: float
WATER_RAMAN_SHIFT_CM: float

FloatArray = npt.NDArray[np.float64]
ArrayLike = Union[npt.ArrayLike, Sequence[float]]
PathLike = Union[str, "os.PathLike[str]"]

class _SpectrumLike(Protocol):
    """Any object with ``.wavelengths`` and ``.values`` (e.g. colour's SpectralDistribution)."""

    @property
    def wavelengths(self) -> Any: ...
    @property
    def values(self) -> Any: ...

LightLike = Union[str, "os.PathLike[str]", "Light", Tuple[ArrayLike, ArrayLike], _SpectrumLike]
"""A built-in light name (d65, a, f11, uv), a CSV path, a Light, a pair
(wavelengths, values) or an object with .wavelengths and .values."""

Lights = Union[LightLike, Sequence[LightLike]]

class FluoriteError(ValueError):
    """A fluorite operation failed; the message is the command line's."""

class Light:
    """A light source: relative spectral power, zero outside its samples."""

    def __init__(self, name_or_path: PathLike) -> None: ...
    @staticmethod
    def from_samples(wavelengths: ArrayLike, values: ArrayLike, name: str = "custom") -> "Light": ...
    @property
    def name(self) -> str: ...
    @property
    def wavelengths(self) -> FloatArray: ...
    @property
    def values(self) -> FloatArray: ...

class Measurement:
    """A reradiation matrix; ``values`` is (n_excitation, n_emission), NaN = missing."""

    def __init__(
        self,
        excitation: ArrayLike,
        emission: ArrayLike,
        values: ArrayLike,
        *,
        name: str = "measurement",
        per_nm: bool = False,
        units: Literal["radiance-factor", "auto", "percent", "arbitrary"] = "radiance-factor",
        keep_scatter: bool = False,
    ) -> None: ...
    @property
    def excitation(self) -> FloatArray:
        """Excitation wavelengths (nm), shape (n_excitation,)."""
    @property
    def emission(self) -> FloatArray:
        """Emission wavelengths (nm), shape (n_emission,)."""
    @property
    def values(self) -> FloatArray:
        """The matrix, shape (n_excitation, n_emission), NaN = missing (a copy)."""
    @property
    def shape(self) -> Tuple[int, int]: ...
    @property
    def name(self) -> str: ...
    @property
    def source(self) -> Optional[str]: ...
    @property
    def sha256(self) -> Optional[str]: ...
    @property
    def kind(self) -> Literal["surface", "instrument-eem"]: ...
    @property
    def per_nm(self) -> bool: ...
    @property
    def has_diagonal(self) -> bool: ...
    @property
    def arbitrary_scale(self) -> bool: ...
    @property
    def preprocessing(self) -> Optional[Dict[str, Any]]: ...
    @property
    def notes(self) -> List[str]: ...

class Fluorophore:
    """One fluorescent component: a(λ), e(λ), c and the yield of its form."""

    def __init__(
        self,
        absorption: Tuple[ArrayLike, ArrayLike],
        emission: Tuple[ArrayLike, ArrayLike],
        concentration: float,
        quantum_yield: float,
        *,
        yield_form: Literal["energy", "photon"] = "energy",
    ) -> None: ...
    @property
    def absorption(self) -> Tuple[FloatArray, FloatArray]: ...
    @property
    def emission(self) -> Tuple[FloatArray, FloatArray]: ...
    @property
    def concentration(self) -> float: ...
    @property
    def quantum_yield(self) -> float: ...
    @property
    def yield_form(self) -> Literal["energy", "photon"]: ...
    @property
    def k(self) -> float: ...
    @property
    def concentration_range(self) -> Optional[Tuple[float, float]]: ...
    @property
    def mean_emission(self) -> float: ...

class Material:
    """A diffuse fluorescent material (fluorite-material/1)."""

    def __init__(
        self,
        name: str,
        wavelengths: ArrayLike,
        reflectance: ArrayLike,
        fluorophores: Optional[Sequence[Fluorophore]] = None,
    ) -> None: ...
    @staticmethod
    def load(path: PathLike) -> "Material": ...
    @staticmethod
    def from_json(text: str) -> "Material": ...
    def to_json(self) -> str: ...
    def save(self, path: PathLike) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def reflectance(self) -> Tuple[FloatArray, FloatArray]: ...
    @property
    def fluorophores(self) -> List[Fluorophore]: ...
    @property
    def report(self) -> Optional[Dict[str, Any]]: ...
    def matrix(
        self,
        excitation: Optional[ArrayLike] = None,
        emission: Optional[ArrayLike] = None,
        *,
        per_nm: bool = False,
    ) -> FloatArray:
        """The predicted matrix, shape (len(excitation), len(emission))."""
    def colour(self, light: Optional[LightLike] = None) -> Dict[str, Any]:
        """{'xyz', 'lab', 'white' (arrays; white Y = 100), 'light' (name)}."""
    def total_radiance_factor(
        self, light: Optional[LightLike] = None, wavelengths: Optional[ArrayLike] = None
    ) -> FloatArray: ...
    def check(self) -> List[Dict[str, Any]]:
        """The broken laws (empty when the material conserves)."""
    @staticmethod
    def check_file(path: PathLike) -> List[Dict[str, Any]]:
        """Every broken law of a material file, read leniently."""
    def export(
        self,
        to: Literal["csv", "matrix", "bfc", "mitsuba", "pbrt", "pearray", "art", "exr", "rgb"],
        path: PathLike,
        *,
        excitation: Optional[Union[ArrayLike, str]] = None,
        emission: Optional[Union[ArrayLike, str]] = None,
        per_nm: bool = False,
        lights: Optional[Lights] = None,
        space: Optional[Literal["srgb", "xyz"]] = None,
    ) -> List[str]: ...

class Fit:
    """A fit's material (or shapes) and report."""

    @property
    def material(self) -> Optional[Material]: ...
    @property
    def shapes(self) -> Optional[Dict[str, Any]]: ...
    @property
    def delta_e(self) -> Dict[str, float]: ...
    @property
    def delta_e_noise(self) -> Dict[str, float]:
        """Per light, the RMS ΔE2000 the cells' noise alone gives the measured colour."""
    @property
    def crosstalk(self) -> Optional[Dict[str, Any]]:
        """Crosstalk next to the diagonal: fractions below/above, errors, worth, removed, note."""
    @property
    def report(self) -> Dict[str, Any]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def converged(self) -> bool: ...
    @property
    def model(self) -> str: ...
    @property
    def seconds(self) -> float: ...
    @property
    def measurement(self) -> Measurement: ...
    @property
    def predicted(self) -> Optional[FloatArray]:
        """The fitted model's matrix on the measurement's grids, (n_excitation, n_emission)."""
    def to_json(self) -> str: ...
    def save(self, path: PathLike) -> None: ...

class ParafacFit:
    """One PARAFAC model (K components) of a set of EEMs."""

    @property
    def components(self) -> int: ...
    @property
    def samples(self) -> List[str]: ...
    @property
    def excitation(self) -> FloatArray: ...
    @property
    def emission(self) -> FloatArray: ...
    @property
    def excitation_loadings(self) -> FloatArray:
        """(K, n_excitation), each row max 1."""
    @property
    def emission_loadings(self) -> FloatArray:
        """(K, n_emission), each row ∫e dλ = 1."""
    @property
    def scores(self) -> FloatArray:
        """(n_samples, K)."""
    @property
    def shares(self) -> FloatArray: ...
    @property
    def explained_variance(self) -> float: ...
    @property
    def core_consistency(self) -> float: ...
    @property
    def split_half(self) -> Optional[Dict[str, Any]]: ...
    @property
    def residual_per_sample(self) -> FloatArray: ...
    @property
    def converged(self) -> bool: ...
    @property
    def iterations(self) -> int: ...
    @property
    def matches(self) -> Optional[List[Dict[str, Any]]]: ...
    @property
    def report(self) -> Dict[str, Any]: ...
    def to_json(self) -> str: ...

class JointResult:
    """PARAFAC models of EEMs (``fits``) or a concentration series (``series``)."""

    @property
    def kind(self) -> Literal["parafac", "series"]: ...
    @property
    def fits(self) -> List[ParafacFit]: ...
    @property
    def series(self) -> Optional[Dict[str, Any]]: ...
    @property
    def materials(self) -> List[Material]: ...
    @property
    def concentrations(self) -> Optional[FloatArray]: ...
    @property
    def excitation_loadings(self) -> FloatArray: ...
    @property
    def emission_loadings(self) -> FloatArray: ...
    @property
    def excitation(self) -> FloatArray: ...
    @property
    def emission(self) -> FloatArray: ...
    @property
    def scores(self) -> FloatArray: ...
    @property
    def explained_variance(self) -> float: ...
    @property
    def core_consistency(self) -> float: ...
    @property
    def split_half(self) -> Optional[Dict[str, Any]]: ...
    def write(self, dir: PathLike) -> List[str]: ...

class ImageFit:
    """An image fit's outcome: K, the trials, the material map and the files written."""

    @property
    def components(self) -> int:
        """K, the number of fluorophores every pixel shares."""
    @property
    def trials(self) -> List[Dict[str, Any]]:
        """Each K tried: components, share_within, median/p99/max_delta_e ({light: ΔE2000}),
        residual_share, iterations, converged."""
    @property
    def masked_pixels(self) -> int: ...
    @property
    def non_finite_cells(self) -> int: ...
    @property
    def clamped_pixels(self) -> int: ...
    @property
    def notes(self) -> List[str]: ...
    @property
    def files(self) -> List[str]: ...
    @property
    def map_path(self) -> str: ...
    @property
    def map(self) -> "MaterialMap": ...
    @property
    def lights(self) -> List[str]: ...
    @property
    def resumed(self) -> List[str]: ...

class MaterialMap:
    """A material map (fluorite-material-map/1): shared fluorophores, per-pixel textures."""

    @staticmethod
    def load(path: PathLike) -> "MaterialMap": ...
    @property
    def path(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def fluorophores(self) -> List[Fluorophore]: ...
    @property
    def gauge(self) -> str: ...
    @property
    def report(self) -> Optional[Dict[str, Any]]: ...
    def concentration(self) -> npt.NDArray[np.float32]:
        """(height, width, K) float32; NaN at masked pixels."""
    def reflectance(self) -> Tuple[FloatArray, npt.NDArray[np.float32]]:
        """(wavelengths (n,), values (height, width, n) float32)."""
    def material_at(self, x: int, y: int) -> Material:
        """The material of pixel (column x, row y)."""
    def to_json(self) -> str: ...

Units = Literal["auto", "radiance-factor", "percent", "arbitrary"]
Format = Literal["wide", "long", "bfc", "webfluor", "exr"]
Paths = Union[PathLike, Sequence[PathLike]]

def read(
    path: PathLike,
    *,
    format: Optional[Format] = None,
    rows: Optional[Literal["excitation", "emission"]] = None,
    zero_is_missing: Optional[bool] = None,
    per_nm: bool = False,
    units: Units = "auto",
    blank: Optional[Paths] = None,
    absorbance: Optional[Paths] = None,
    keep_scatter: bool = False,
    scatter_width: Optional[Dict[str, float]] = None,
    bandwidth: Optional[float] = None,
    raman_shift: float = 3400.0,
) -> Measurement:
    """Reads a reradiation matrix; values (n_excitation, n_emission), NaN = missing."""

def fit(
    measurement_or_path: Union[Measurement, PathLike],
    *,
    lights: Optional[Lights] = None,
    model: Optional[str] = None,
    max_delta_e: Optional[float] = None,
    yield_form: Literal["auto", "energy", "photon"] = "auto",
    quantum_yield: Optional[float] = None,
    concentration: Optional[float] = None,
    guard: Optional[float] = None,
    solver: Literal["lbfgs", "gauss-newton", "nelder-mead", "init"] = "lbfgs",
    start: Literal["closed-form", "flat"] = "closed-form",
    max_iterations: int = 500,
    tolerance: float = ...,
    colour_weight: float = ...,
    noise_aware_bound: bool = False,
    band_axis: Literal["both", "wavenumber", "wavelength"] = "both",
    format: Optional[Format] = None,
    rows: Optional[Literal["excitation", "emission"]] = None,
    zero_is_missing: Optional[bool] = None,
    per_nm: Optional[bool] = None,
    units: Optional[Units] = None,
    blank: Optional[Paths] = None,
    absorbance: Optional[Paths] = None,
    keep_scatter: Optional[bool] = None,
    scatter_width: Optional[Dict[str, float]] = None,
    bandwidth: Optional[float] = None,
    raman_shift: Optional[float] = None,
) -> Fit:
    """Fits the fluorescent BBRRDF to a measurement or file (GIL released)."""

def fit_many(
    items: Sequence[Union[Measurement, PathLike]],
    *,
    threads: Optional[int] = None,
    errors: Literal["raise", "return"] = "raise",
    lights: Optional[Lights] = None,
    model: Optional[str] = None,
    max_delta_e: Optional[float] = None,
    yield_form: Literal["auto", "energy", "photon"] = "auto",
    quantum_yield: Optional[float] = None,
    concentration: Optional[float] = None,
    guard: Optional[float] = None,
    solver: Literal["lbfgs", "gauss-newton", "nelder-mead", "init"] = "lbfgs",
    start: Literal["closed-form", "flat"] = "closed-form",
    max_iterations: int = 500,
    tolerance: float = ...,
    colour_weight: float = ...,
    noise_aware_bound: bool = False,
    band_axis: Literal["both", "wavenumber", "wavelength"] = "both",
    format: Optional[Format] = None,
    rows: Optional[Literal["excitation", "emission"]] = None,
    zero_is_missing: Optional[bool] = None,
    per_nm: Optional[bool] = None,
    units: Optional[Units] = None,
    blank: Optional[Paths] = None,
    absorbance: Optional[Paths] = None,
    keep_scatter: Optional[bool] = None,
    scatter_width: Optional[Dict[str, float]] = None,
    bandwidth: Optional[float] = None,
    raman_shift: Optional[float] = None,
) -> List[Union[Fit, FluoriteError]]:
    """Fits several items on a pool of Rust threads (GIL released), in input order."""

def joint(
    measurements: Sequence[Union[Measurement, PathLike]],
    *,
    components: Optional[Union[int, Sequence[int], range]] = None,
    em_range: Optional[Tuple[float, float]] = None,
    ex_range: Optional[Tuple[float, float]] = None,
    no_split_half: bool = False,
    max_iterations: int = 500,
    lights: Optional[Lights] = None,
    yield_form: Literal["auto", "energy", "photon"] = "auto",
    guard: Optional[float] = None,
    reference: Optional[PathLike] = None,
    format: Optional[Format] = None,
    rows: Optional[Literal["excitation", "emission"]] = None,
    zero_is_missing: Optional[bool] = None,
    per_nm: Optional[bool] = None,
    units: Optional[Units] = None,
    blank: Optional[Paths] = None,
    absorbance: Optional[Paths] = None,
    keep_scatter: Optional[bool] = None,
    scatter_width: Optional[Dict[str, float]] = None,
    bandwidth: Optional[float] = None,
    raman_shift: Optional[float] = None,
) -> JointResult:
    """Joint fit of a sample set: PARAFAC of EEMs, or a concentration series."""

def render(
    material: Material,
    *,
    light: Optional[LightLike] = None,
    scene: Literal["preview", "furnace"] = "preview",
    spp: int = 64,
    size: Optional[Tuple[int, int]] = None,
    seed: int = 1,
    compare: bool = False,
    exposure: Optional[float] = None,
    adapt: bool = True,
    sampling: Literal["light", "paper"] = "light",
) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint8]]:
    """Renders the material: (linear float32 HxWx3, sRGB uint8 HxWx3)."""

ImageSource = Union[PathLike, npt.ArrayLike]
"""A bispectral OpenEXR path, or an array (height, width, n_excitation, n_emission)."""

def fit_image(
    source: ImageSource,
    *,
    output: PathLike,
    components: Optional[int] = None,
    max_components: int = 4,
    max_delta_e: float = 1.0,
    share: float = 0.99,
    lights: Optional[Lights] = None,
    yield_form: Literal["auto", "energy", "photon"] = "auto",
    zip: bool = False,
    excitation_nm: Optional[ArrayLike] = None,
    emission_nm: Optional[ArrayLike] = None,
) -> ImageFit:
    """Fits a bispectral image (EXR path or array) into a material map (GIL released)."""

def write_image(
    path: PathLike,
    source: npt.ArrayLike,
    *,
    excitation_nm: ArrayLike,
    emission_nm: ArrayLike,
    half: bool = False,
    zip: bool = False,
) -> str:
    """Writes an array (height, width, n_excitation, n_emission) as a bispectral OpenEXR."""

class _ImageStages:
    """The stages of one image fit, for ``fluorite.dask`` (private: its API may change).

    ``source`` is a bispectral OpenEXR path, or None with ``excitation_nm``,
    ``emission_nm`` and ``shape`` (height, width) for an image whose rows come with each
    pass as arrays (rows, width, excitation, emission). Each pass returns its blocks'
    contributions (summed in block order by the caller) or records; GIL released."""

    def __init__(
        self,
        source: Optional[PathLike],
        *,
        components: Optional[int] = None,
        max_components: int = 4,
        max_delta_e: float = 1.0,
        share: float = 0.99,
        lights: Optional[Lights] = None,
        yield_form: Literal["auto", "energy", "photon"] = "auto",
        zip: bool = False,
        excitation_nm: Optional[ArrayLike] = None,
        emission_nm: Optional[ArrayLike] = None,
        shape: Optional[Tuple[int, int]] = None,
    ) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def cells(self) -> int: ...
    @property
    def m(self) -> int: ...
    @property
    def rank(self) -> int: ...
    @property
    def power_steps(self) -> int: ...
    @property
    def record_len(self) -> int: ...
    @property
    def diagonal_nm(self) -> List[float]: ...
    @property
    def cell_grid(self) -> Optional[List[Tuple[int, int]]]:
        """Each layout cell's (excitation, emission) index, canonical order (arrays only)."""
    @property
    def block_rows(self) -> Optional[int]: ...
    def block_rects(self) -> List[Tuple[int, int, int, int]]:
        """Each block of a pass, in order: (x, y, width, height)."""
    def sketch(
        self, first: int = 0, count: int = 0, pixels: Optional[npt.ArrayLike] = None, y: int = 0
    ) -> Tuple[npt.NDArray[np.float32], int, int]:
        """Pass 1: (contributions (blocks, m, rank), masked pixels, non-finite cells)."""
    def power(
        self,
        basis: FloatArray,
        first: int = 0,
        count: int = 0,
        pixels: Optional[npt.ArrayLike] = None,
        y: int = 0,
    ) -> npt.NDArray[np.float32]:
        """A power step: contributions (blocks, m, rank)."""
    def project(
        self,
        basis: FloatArray,
        first: int = 0,
        count: int = 0,
        pixels: Optional[npt.ArrayLike] = None,
        y: int = 0,
    ) -> List[Tuple[int, int, npt.NDArray[np.float32]]]:
        """Pass 3: (x, y, records (height, width, record_len)) per block."""
    def read_blocks(self, first: int, count: int) -> List[Tuple[int, int, npt.NDArray[np.float32]]]:
        """An EXR's cells: (x, y, cells (height, width, cells)) per block."""
    def orthonormal(self, z: FloatArray) -> FloatArray:
        """An orthonormal basis (m, rank) of the range of z (m, rank)."""
    def fit_records(
        self,
        output: PathLike,
        basis: FloatArray,
        masked_pixels: int,
        non_finite_cells: int,
        read_rows: Callable[[int, int], npt.ArrayLike],
        map_chunks: Optional[Callable[[str, int], List[str]]] = None,
        map_bands: Optional[Callable[[str], Iterable[Tuple[int, int, bytes]]]] = None,
        fetch_pixels: Optional[Callable[[int, int], npt.ArrayLike]] = None,
    ) -> ImageFit:
        """The fit after the passes, from the records read_rows(y, rows) returns; with
        map_chunks(kernel, chunks), the passes over the records run through it (the
        results of run_records on every chunk of RECORD_CHUNK records, in order); with
        map_bands(job) (uncompressed outputs), the EXR outputs' tiles are written by it:
        (y, clamped, png) of write_band on bands of whole rows of 64-pixel tiles, in row
        order; the PNGs are encoded here from their rows. With fetch_pixels(first, count)
        returning (count, record_len) float32, the records are read through it when
        needed instead of copied through read_rows."""
    RECORD_CHUNK: int
    """Records per chunk of a pass over the records."""
    def run_records(
        self, basis: FloatArray, kernel: str, first: int, records: npt.NDArray[np.float32]
    ) -> List[str]:
        """A pass's results on records (n, record_len) of pixels first..first + n, one per chunk."""
    def write_band(
        self, job: str, basis: FloatArray, y: int, records: npt.NDArray[np.float32]
    ) -> Tuple[int, bytes]:
        """Writes rows y..y + rows (records (rows, width, record_len), whole rows of tiles)
        of every EXR output of job into its staged files; returns (clamped pixels, PNG rows)."""
    def model_of(self, fit: ImageFit) -> str:
        """The model of a finished fit's pixels (JSON) for evaluate."""
    def evaluate(
        self, model: str, basis: FloatArray, records: npt.NDArray[np.float32]
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """(concentration (h, w, K), reflectance (h, w, n), ΔE2000 (h, w, lights)) of records (h, w, record_len)."""
