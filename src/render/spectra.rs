//! Spectra as the renderer uses them: tabulated once at 1 nm over the rendered range
//! (300–780 nm) in f32, with the sampling tables a path needs at a fluorescent event
//! (model.md §6) and for choosing the wavelengths a camera path carries.

use std::ops::{Add, Mul, Sub};

use glam::Vec4;

use crate::colour::{Light, cie1931};
use crate::error::{Error, Result};
use crate::material::{Material, YieldForm};

/// Shortest wavelength the renderer carries (nm): UV excitation from here on can reach
/// visible emission.
pub const LAMBDA_MIN_NM: f32 = 300.0;
/// Longest wavelength the renderer carries (nm).
pub const LAMBDA_MAX_NM: f32 = 780.0;
/// Entries of a 1 nm table over [`LAMBDA_MIN_NM`, `LAMBDA_MAX_NM`].
pub const TABLE_LEN: usize = 481;
const LAST_INTERVAL: usize = TABLE_LEN - 2;

/// The wavelength of table entry `i` (nm).
fn table_nm(i: usize) -> f64 {
    LAMBDA_MIN_NM as f64 + i as f64
}

/// A spectrum tabulated at every whole nanometre from 300 to 780 nm and linear in
/// between. Material spectra are linear between their samples, so for samples at whole
/// nanometres the table reproduces them exactly.
#[derive(Debug, Clone)]
pub struct Table {
    pub(super) values: Vec<f32>,
}

/// Where four wavelengths fall in the 1 nm tables: computed once per wavelength change
/// and shared by every table read at those wavelengths.
#[derive(Debug, Clone, Copy)]
pub struct Lookup {
    index: [usize; 4],
    frac: Vec4,
}

impl Lookup {
    /// The table positions of four wavelengths (clamped to the table's range).
    #[inline]
    pub fn new(nm: Vec4) -> Lookup {
        let x = (nm - Vec4::splat(LAMBDA_MIN_NM))
            .clamp(Vec4::ZERO, Vec4::splat((TABLE_LEN - 1) as f32));
        let whole = x.floor().min(Vec4::splat(LAST_INTERVAL as f32));
        let i = whole.to_array();
        Lookup {
            // Through i32: a plain truncation, cheaper than f32 → usize's saturating cast.
            index: i.map(|v| v as i32 as usize),
            frac: x - whole,
        }
    }
}

/// The entry of a 1 nm `table` (from [`LAMBDA_MIN_NM`]) at `nm`, linear between entries
/// and clamped to the table's range: for scalar tables and the colour-matching functions.
#[inline]
fn interpolate<T>(table: &[T], nm: f32) -> T
where
    T: Copy + Add<Output = T> + Sub<Output = T>,
    f32: Mul<T, Output = T>,
{
    let x = (nm - LAMBDA_MIN_NM).clamp(0.0, (TABLE_LEN - 1) as f32);
    let i = (x as i32 as usize).min(LAST_INTERVAL);
    let t = x - i as f32;
    table[i] + t * (table[i + 1] - table[i])
}

impl Table {
    /// Tabulates `f` at 300, 301, …, 780 nm.
    pub fn from_fn(f: impl Fn(f64) -> f64) -> Table {
        Table {
            values: (0..TABLE_LEN).map(|i| f(table_nm(i)) as f32).collect(),
        }
    }

    /// A table from its 481 values (entry i at 300 + i nm); shorter input is padded
    /// with its last value (zero when empty), longer input cut.
    pub fn from_values(mut values: Vec<f32>) -> Table {
        let last = values.last().copied().unwrap_or(0.0);
        values.resize(TABLE_LEN, last);
        Table { values }
    }

    /// A constant spectrum.
    pub fn constant(value: f32) -> Table {
        Table {
            values: vec![value; TABLE_LEN],
        }
    }

    /// Value at `nm`, linear between entries (clamped to the table's range).
    #[inline]
    pub fn eval(&self, nm: f32) -> f32 {
        interpolate(&self.values, nm)
    }

    /// Values at four wavelengths at once.
    #[inline]
    pub fn eval4(&self, nm: Vec4) -> Vec4 {
        self.gather(&Lookup::new(nm))
    }

    /// Values at the four wavelengths of a lookup.
    #[inline]
    pub fn gather(&self, at: &Lookup) -> Vec4 {
        let v = &self.values;
        let [a, b, c, d] = at.index;
        let lo = Vec4::new(v[a], v[b], v[c], v[d]);
        let hi = Vec4::new(v[a + 1], v[b + 1], v[c + 1], v[d + 1]);
        lo + at.frac * (hi - lo)
    }

    /// ∫ value dλ over 300–780 nm (trapezoid rule, exact for the table's interpolant).
    pub fn integral(&self) -> f64 {
        self.values
            .windows(2)
            .map(|w| 0.5 * (w[0] as f64 + w[1] as f64))
            .sum()
    }

    /// ∫ self·other dλ over 300–780 nm, exact for the product of the two piecewise-linear
    /// interpolants.
    pub fn integral_of_product(&self, other: &Table) -> f64 {
        self.values
            .windows(2)
            .zip(other.values.windows(2))
            .map(|(a, b)| {
                let (a0, a1, b0, b1) = (a[0] as f64, a[1] as f64, b[0] as f64, b[1] as f64);
                (2.0 * a0 * b0 + a0 * b1 + a1 * b0 + 2.0 * a1 * b1) / 6.0
            })
            .sum()
    }

    /// The tabulated values (entry i at 300 + i nm).
    pub fn values(&self) -> &[f32] {
        &self.values
    }

    fn max(&self) -> f32 {
        self.values.iter().cloned().fold(0.0, f32::max)
    }
}

/// Cumulative distribution over the 480 one-nanometre intervals of a table, for drawing
/// wavelengths with a density proportional to the table (piecewise linear) or to a
/// piecewise-constant weight.
#[derive(Debug, Clone)]
pub(super) struct IntervalCdf {
    /// cdf[i] = probability of the intervals before i; cdf[480] = 1.
    cdf: Vec<f32>,
    /// 1 / (cdf[i + 1] − cdf[i]), 0 for intervals without mass.
    inverse_mass: Vec<f32>,
    /// guide[g] = the interval holding u = g / GUIDE_CELLS: where the search for any u
    /// in that cell starts (Chen's guide table, a constant expected number of steps).
    guide: Vec<u16>,
}

const GUIDE_CELLS: usize = 4096;

impl IntervalCdf {
    /// From the masses of the 480 intervals; None when they sum to zero.
    pub(super) fn new(masses: impl Iterator<Item = f64>) -> Option<IntervalCdf> {
        let mut cdf = Vec::with_capacity(TABLE_LEN);
        let mut sum = 0.0;
        cdf.push(0.0);
        for m in masses {
            sum += m.max(0.0);
            cdf.push(sum);
        }
        if sum <= 0.0 || !sum.is_finite() {
            return None;
        }
        let cdf: Vec<f32> = cdf.iter().map(|c| (c / sum) as f32).collect();
        let guide = (0..GUIDE_CELLS)
            .map(|g| {
                let u = g as f32 / GUIDE_CELLS as f32;
                (cdf.partition_point(|&c| c <= u).max(1) - 1).min(LAST_INTERVAL) as u16
            })
            .collect();
        let inverse_mass = cdf
            .windows(2)
            .map(|w| {
                if w[1] > w[0] {
                    1.0 / (w[1] - w[0])
                } else {
                    0.0
                }
            })
            .collect();
        Some(IntervalCdf {
            cdf,
            inverse_mass,
            guide,
        })
    }

    /// The interval holding `u` in [0, 1) and where `u` falls inside its mass, in [0, 1).
    #[inline]
    pub(super) fn locate(&self, u: f32) -> (usize, f32) {
        let cell = ((u * GUIDE_CELLS as f32) as i32 as usize).min(GUIDE_CELLS - 1);
        let mut i = self.guide[cell] as usize;
        while i < LAST_INTERVAL && self.cdf[i + 1] <= u {
            i += 1;
        }
        // An interval without mass (u exactly on a flat stretch of the CDF) gives v = 0.
        let v = ((u - self.cdf[i]) * self.inverse_mass[i]).clamp(0.0, 0.999_999);
        (i, v)
    }

    pub(super) fn mass(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }
}

/// Where in [0, 1] a point falls when drawn from the density ∝ y0 + (y1 − y0)·t on
/// [0, 1], given `v`, the uniform fraction of the interval's mass below it.
#[inline]
pub(super) fn linear_inverse(y0: f32, y1: f32, v: f32) -> f32 {
    // Solve y0·t + (y1 − y0)·t²/2 = v·(y0 + y1)/2 in the cancellation-free form.
    let den = y0 + (y0 * y0 + v * (y1 * y1 - y0 * y0)).max(0.0).sqrt();
    let t = if den > 0.0 { v * (y0 + y1) / den } else { v };
    t.clamp(0.0, 1.0)
}

/// The light-aware excitation sampler of a fluorophore under a scene's light L: the
/// density ĝ/B, where ĝ is the piecewise-linear interpolant of g = x·a·L between the
/// 1 nm nodes (x the yield form's excitation factor) and B = ∫ĝ dλ.
#[derive(Debug, Clone)]
pub struct LitExcitation {
    /// g = x·a·L at each node (entry i at 300 + i nm).
    pub product: Table,
    /// B = ∫ĝ dλ: the light this fluorophore absorbs per unit of its yield scale.
    pub absorbed: f32,
    cdf: IntervalCdf,
}

impl LitExcitation {
    /// The sampler for excitation factor × absorption `xa` (at the nodes) under `light`;
    /// None when the fluorophore absorbs none of the light.
    fn new(xa: &[f32], light: &Table) -> Option<LitExcitation> {
        let product = Table {
            values: xa
                .iter()
                .zip(&light.values)
                .map(|(a, l)| (a * l).max(0.0))
                .collect(),
        };
        let masses: Vec<f64> = product
            .values
            .windows(2)
            .map(|w| 0.5 * (w[0] as f64 + w[1] as f64))
            .collect();
        let absorbed = masses.iter().sum::<f64>() as f32;
        if !(absorbed > 0.0 && absorbed.is_finite()) {
            return None;
        }
        let cdf = IntervalCdf::new(masses.into_iter())?;
        Some(LitExcitation {
            product,
            absorbed,
            cdf,
        })
    }

    /// Draws an excitation wavelength with density exactly ĝ(λ)/B from `u` in [0, 1).
    #[inline]
    pub fn sample(&self, u: f32) -> f32 {
        let (i, v) = self.cdf.locate(u);
        let g = &self.product.values;
        LAMBDA_MIN_NM + i as f32 + linear_inverse(g[i], g[i + 1], v)
    }
}

/// One fluorophore as a camera path meets it: its yield scale k, absorption and
/// emission, and a sampler for the excitation wavelength with density x(λ)·a(λ)/A, where
/// x is the excitation factor of the yield form: 1 in the energy form, λ/λ̄e in the
/// photon form (the energy yield Φ·λ/λ̄e grows with λ).
#[derive(Debug, Clone)]
pub struct FluorophoreTables {
    /// k = c·Q (energy form) or c·Φ (photon form).
    pub k: f32,
    /// The yield form.
    pub yield_form: YieldForm,
    /// λ̄e (nm): the photon form's excitation factor is λ/λ̄e.
    pub emission_mean_nm: f64,
    /// a(λ).
    pub absorption: Table,
    /// e(λ) (1/nm).
    pub emission: Table,
    /// A = ∫x·a dλ over the rendered range (∫a in the energy form, ∫λ·a dλ/λ̄e in the
    /// photon form), exact for the table's piecewise-linear a.
    pub absorption_integral: f32,
    /// k·A·e(λo): this fluorophore's share of the fluorescent albedo at λo.
    pub albedo: Table,
    /// The light-aware sampler under the scene's light (set by
    /// [`SurfaceTables::light_with`]); None before, or when it absorbs none of the light.
    pub lit: Option<LitExcitation>,
    cdf: Option<IntervalCdf>,
}

/// Proposals the photon form's excitation sampler may reject before it keeps one; each
/// is accepted with probability ≥ 300/301, so this is never reached in practice.
const MAX_EXCITATION_PROPOSALS: usize = 64;

impl FluorophoreTables {
    /// The tables of one fluorophore of a material.
    pub(super) fn new(f: &crate::material::Fluorophore) -> FluorophoreTables {
        let absorption = Table::from_fn(|nm| f.absorption.eval_zero_outside(nm));
        let emission = Table::from_fn(|nm| f.emission.eval_zero_outside(nm));
        let emission_mean_nm = f.emission_mean_nm();
        // Per 1 nm interval [λj, λj + 1] with a linear from a0 to a1: ∫a = (a0 + a1)/2,
        // and ∫λ·a = λj·(a0 + a1)/2 + (a0 + 2·a1)/6 (exact).
        let masses: Vec<f64> = absorption
            .values
            .windows(2)
            .enumerate()
            .map(|(j, w)| {
                let (a0, a1) = (w[0] as f64, w[1] as f64);
                match f.yield_form {
                    YieldForm::Energy => 0.5 * (a0 + a1),
                    YieldForm::Photon => {
                        (table_nm(j) * 0.5 * (a0 + a1) + (a0 + 2.0 * a1) / 6.0) / emission_mean_nm
                    }
                }
            })
            .collect();
        let absorption_integral = masses.iter().sum::<f64>() as f32;
        let k = f.k() as f32;
        let albedo = Table {
            values: emission
                .values
                .iter()
                .map(|e| k * absorption_integral * e)
                .collect(),
        };
        // A photon-form fluorophore whose emission has no mean (no emission) never fires.
        let cdf = if absorption_integral.is_finite() {
            IntervalCdf::new(masses.into_iter())
        } else {
            None
        };
        FluorophoreTables {
            k,
            yield_form: f.yield_form,
            emission_mean_nm,
            absorption,
            emission,
            absorption_integral,
            albedo,
            lit: None,
            cdf,
        }
    }

    /// Builds the light-aware excitation sampler under a scene's light spectrum `light`
    /// ([`FluorophoreTables::lit`]).
    pub(super) fn light_with(&mut self, light: &Table) {
        let xa: Vec<f32> = self
            .absorption
            .values
            .iter()
            .enumerate()
            .map(|(i, a)| a * self.excitation_factor(table_nm(i) as f32))
            .collect();
        self.lit = LitExcitation::new(&xa, light);
    }

    /// True when the fluorophore absorbs in the rendered range and emits there: one that
    /// does not never fires, and surfaces drop it from their sampling.
    pub(super) fn fires(&self) -> bool {
        self.cdf.is_some() && self.albedo.max() > 0.0
    }

    /// The yield form's excitation factor x(λ): 1 (energy form) or λ/λ̄e (photon form).
    #[inline]
    pub fn excitation_factor(&self, nm: f32) -> f32 {
        match self.yield_form {
            YieldForm::Energy => 1.0,
            YieldForm::Photon => (nm as f64 / self.emission_mean_nm) as f32,
        }
    }

    /// Draws an excitation wavelength with density exactly x(λ)·a(λ)/A for the table's
    /// piecewise-linear a: an interval by its exact mass, then a point inside it by
    /// inverting the linear density a's quadratic CDF. In the photon form that point is
    /// kept with probability λ/(λj + 1) (λj the interval's start), else another is drawn
    /// with `next()`: the kept point then has density ∝ λ·a(λ) in the interval, exactly.
    /// `u` and `next()` are uniform in [0, 1).
    #[inline]
    pub fn sample_excitation(&self, u: f32, mut next: impl FnMut() -> f32) -> f32 {
        let Some(cdf) = &self.cdf else {
            return LAMBDA_MIN_NM;
        };
        let (i, mut v) = cdf.locate(u);
        let a0 = self.absorption.values[i];
        let a1 = self.absorption.values[i + 1];
        let start = LAMBDA_MIN_NM + i as f32;
        let point = |v: f32| start + linear_inverse(a0, a1, v);
        match self.yield_form {
            YieldForm::Energy => point(v),
            YieldForm::Photon => {
                let end = start + 1.0;
                let mut nm = point(v);
                for _ in 0..MAX_EXCITATION_PROPOSALS {
                    if next() * end < nm {
                        break;
                    }
                    v = next();
                    nm = point(v);
                }
                nm
            }
        }
    }
}

/// A surface's spectral behaviour for a camera path (model.md §6): the diagonal
/// reflectance d(λ) = (1 − Σc·a)·r, the fluorescent albedo F(λo) = Σ k·A·e(λo) (A = ∫x·a,
/// x = 1 or λ/λ̄e by the yield form), and the fluorophores to sample the excitation
/// wavelength from.
#[derive(Debug, Clone)]
pub struct SurfaceTables {
    /// A short name for messages.
    pub name: String,
    /// d(λ).
    pub diagonal: Table,
    /// F(λo) = Σ k·A·e(λo): the energy a camera path at λo gathers through fluorescence
    /// per unit incident spectral radiance, were it constant.
    pub fluorescent_albedo: Table,
    /// The fluorophores (empty for a plain Lambertian reflector).
    pub fluorophores: Vec<FluorophoreTables>,
    /// G(λo) = Σ k·B·e(λo), B = ∫x·a·L dλ: the light a camera path at λo gathers through
    /// fluorescence when the incident radiance is the scene's light spectrum L (set by
    /// [`SurfaceTables::light_with`]; zero before).
    pub lit_albedo: Table,
}

impl SurfaceTables {
    /// The tables of a material, checked first with [`Material::validate`].
    pub fn new(material: &Material) -> Result<SurfaceTables> {
        material.validate()?;
        let diagonal = Table::from_fn(|nm| material.diagonal(nm));
        let mut fluorophores = Vec::new();
        for f in &material.fluorophores {
            fluorophores.push(FluorophoreTables::new(f));
        }
        // Fluorophores that absorb nothing in the rendered range or emit nothing there
        // never fire; dropping them keeps the fast path for such surfaces.
        fluorophores.retain(FluorophoreTables::fires);
        let mut fluorescent_albedo = Table::constant(0.0);
        for f in &fluorophores {
            for (total, v) in fluorescent_albedo.values.iter_mut().zip(&f.albedo.values) {
                *total += v;
            }
        }
        Ok(SurfaceTables {
            name: material.name.clone(),
            diagonal,
            fluorescent_albedo,
            fluorophores,
            lit_albedo: Table::constant(0.0),
        })
    }

    /// A spectrally flat, non-fluorescent reflector (the neutral grey ground).
    pub fn grey(name: &str, reflectance: f32) -> SurfaceTables {
        SurfaceTables {
            name: name.to_string(),
            diagonal: Table::constant(reflectance),
            fluorescent_albedo: Table::constant(0.0),
            fluorophores: Vec::new(),
            lit_albedo: Table::constant(0.0),
        }
    }

    /// Builds the light-aware excitation samplers for a scene whose every emitter (area
    /// lights and environment) shares the spectrum `light`, and the lit albedo G.
    pub fn light_with(&mut self, light: &Table) {
        let mut lit_albedo = Table::constant(0.0);
        for f in &mut self.fluorophores {
            f.light_with(light);
            if let Some(lit) = &f.lit {
                for (total, e) in lit_albedo.values.iter_mut().zip(&f.emission.values) {
                    *total += f.k * lit.absorbed * e;
                }
            }
        }
        self.lit_albedo = lit_albedo;
    }

    /// True when the surface has a fluorescent component in the rendered range.
    pub fn is_fluorescent(&self) -> bool {
        !self.fluorophores.is_empty()
    }
}

/// How a light's spectrum was scaled to make renders under different lights comparable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LightNormalisation {
    /// To unit luminance: ∫L·ȳ dλ = 1.
    Luminance,
    /// The light has (almost) no visible power, as a bare UV lamp: scaled to the radiant
    /// power of D65 at unit luminance instead.
    RadiantPower,
}

/// The spectrum every emitter of a scene shares (area light and environment), normalised
/// by [`LightNormalisation`] and tabulated over the rendered range.
#[derive(Debug, Clone)]
pub struct LightSpectrum {
    /// The light's name.
    pub name: String,
    /// Normalised relative spectral radiance.
    pub radiance: Table,
    /// The scale applied to the light's tabulated power.
    pub scale: f64,
    /// How the scale was chosen.
    pub normalisation: LightNormalisation,
    /// XYZ of the normalised light (its white, Y = 1 under luminance normalisation).
    pub white_xyz: [f64; 3],
    /// Mean normalised radiance over 300–780 nm (∫L dλ / 480 nm).
    pub mean_radiance: f32,
}

/// A light whose luminance per radiant power is below this fraction of D65's counts as
/// having no visible power.
const INVISIBLE_LIGHT_FRACTION: f64 = 1e-3;

impl LightSpectrum {
    /// Tabulates and normalises `light`. Fails when it has no power between 300 and
    /// 780 nm.
    pub fn new(light: &Light) -> Result<LightSpectrum> {
        let raw = Table::from_fn(|nm| light.power(nm));
        let observer = Observer::get();
        let radiant = raw.integral();
        if radiant <= 0.0 || !radiant.is_finite() {
            return Err(Error::invalid(
                "light",
                format!(
                    "\"{}\" has no power between {LAMBDA_MIN_NM} and {LAMBDA_MAX_NM} nm, the range the renderer carries; give a light with power there",
                    light.name
                ),
            ));
        }
        let luminance = raw.integral_of_product(&observer.y);
        let d65 = Table::from_fn(|nm| {
            Light::builtin("d65")
                .map(|l| l.power(nm))
                .unwrap_or_default()
        });
        let d65_efficacy = d65.integral_of_product(&observer.y) / d65.integral();
        let (scale, normalisation) =
            if luminance / radiant > INVISIBLE_LIGHT_FRACTION * d65_efficacy {
                (1.0 / luminance, LightNormalisation::Luminance)
            } else {
                (d65_efficacy / radiant, LightNormalisation::RadiantPower)
            };
        let radiance = Table {
            values: raw
                .values
                .iter()
                .map(|v| (*v as f64 * scale) as f32)
                .collect(),
        };
        let white_xyz = [
            radiance.integral_of_product(&observer.x),
            radiance.integral_of_product(&observer.y),
            radiance.integral_of_product(&observer.z),
        ];
        let mean_radiance = (radiance.integral() / (TABLE_LEN - 1) as f64) as f32;
        Ok(LightSpectrum {
            mean_radiance,
            name: light.name.clone(),
            radiance,
            scale,
            normalisation,
            white_xyz,
        })
    }
}

/// The CIE 1931 colour-matching functions over the rendered range, and the density with
/// which camera paths draw their wavelengths: piecewise constant per nanometre,
/// proportional to max(x̄, ȳ, z̄) plus a small floor, zero below 360 nm where the observer
/// sees nothing. Fluorescence still reaches below 360 nm: excitation wavelengths are
/// drawn from the absorption, not from this density.
#[derive(Debug, Clone)]
pub struct Observer {
    /// x̄(λ).
    pub x: Table,
    /// ȳ(λ).
    pub y: Table,
    /// z̄(λ).
    pub z: Table,
    pub(super) cdf: IntervalCdf,
    /// Density of each 1 nm interval (1/nm).
    pub(super) density: Vec<f32>,
    /// (x̄, ȳ, z̄, 0) per table entry, for one read per wavelength.
    pub(super) cmf: Vec<Vec4>,
}

impl Observer {
    /// The shared observer tables (built once).
    pub fn get() -> &'static Observer {
        static OBSERVER: std::sync::OnceLock<Observer> = std::sync::OnceLock::new();
        OBSERVER.get_or_init(|| {
            let cie = cie1931();
            let x = Table::from_fn(|nm| cie.x.eval_zero_outside(nm));
            let y = Table::from_fn(|nm| cie.y.eval_zero_outside(nm));
            let z = Table::from_fn(|nm| cie.z.eval_zero_outside(nm));
            let peak = |i: usize| {
                [&x, &y, &z]
                    .iter()
                    .map(|t| t.values[i])
                    .fold(0.0f32, f32::max) as f64
            };
            let weights: Vec<f64> = (0..TABLE_LEN - 1)
                .map(|i| {
                    let m = peak(i).max(peak(i + 1));
                    // A floor keeps the density positive wherever the observer responds.
                    if m > 0.0 { m + 0.02 } else { 0.0 }
                })
                .collect();
            let cdf = IntervalCdf::new(weights.iter().cloned()).expect("observer has mass");
            let density = (0..TABLE_LEN - 1).map(|i| cdf.mass(i)).collect();
            let cmf = (0..TABLE_LEN)
                .map(|i| Vec4::new(x.values[i], y.values[i], z.values[i], 0.0))
                .collect();
            Observer {
                x,
                y,
                z,
                cdf,
                density,
                cmf,
            }
        })
    }

    /// Draws a wavelength for the camera from `u` in [0, 1); returns it and its density.
    #[inline]
    pub fn sample(&self, u: f32) -> (f32, f32) {
        let (i, v) = self.cdf.locate(u);
        (LAMBDA_MIN_NM + i as f32 + v, self.density[i])
    }

    /// x̄, ȳ, z̄ at `nm`.
    #[inline]
    pub fn xyz(&self, nm: f32) -> [f32; 3] {
        let v = self.cmf4(nm);
        [v.x, v.y, v.z]
    }

    /// (x̄, ȳ, z̄, 0) at `nm`.
    #[inline]
    pub fn cmf4(&self, nm: f32) -> Vec4 {
        interpolate(&self.cmf, nm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle 400–500 nm peaking at 1 at 430 nm (area 50): the lower of its rising
    /// and falling edges, zero outside.
    fn triangle(nm: f64) -> f64 {
        ((nm - 400.0) / 30.0).min((500.0 - nm) / 70.0).max(0.0)
    }

    /// Draws 200 000 stratified excitation wavelengths from `f` (`next` for its second
    /// number) and asserts their histogram in 10 nm bins over 400–500 nm against the exact
    /// bin masses of `density`: midpoint sums of `steps` per bin, over `total`.
    fn assert_excitation_follows(
        f: &FluorophoreTables,
        mut next: impl FnMut() -> f32,
        density: impl Fn(f64) -> f64,
        steps: usize,
        total: f64,
    ) {
        let n = 200_000;
        let mut hist = [0u32; 10];
        for s in 0..n {
            let u = (s as f32 + 0.5) / n as f32;
            let nm = f.sample_excitation(u, &mut next);
            assert!((400.0..=500.0).contains(&nm), "{nm}");
            hist[((nm - 400.0) / 10.0).min(9.0) as usize] += 1;
        }
        let step = 10.0 / steps as f64;
        for (b, count) in hist.iter().enumerate() {
            let lo = 400.0 + 10.0 * b as f64;
            let mass = (0..steps)
                .map(|s| density(lo + (s as f64 + 0.5) * step) * step)
                .sum::<f64>()
                / total;
            let got = *count as f64 / n as f64;
            assert!((got - mass).abs() < 2e-3, "bin {b}: {got} vs {mass}");
        }
    }

    #[test]
    fn spectral_sampling_follows_absorption() {
        // A triangle absorption: the sampled histogram in 10 nm bins must match the exact
        // bin masses.
        let a = Table::from_fn(triangle);
        let cdf = IntervalCdf::new(a.values.windows(2).map(|w| 0.5 * (w[0] + w[1]) as f64));
        let f = FluorophoreTables {
            k: 1.0,
            yield_form: YieldForm::Energy,
            emission_mean_nm: 500.0,
            absorption_integral: a.integral() as f32,
            albedo: Table::constant(0.0),
            emission: Table::constant(0.0),
            absorption: a,
            lit: None,
            cdf,
        };
        let absorption = |nm: f64| f.absorption.eval(nm as f32) as f64;
        let once = || panic!("the energy form draws once");
        assert_excitation_follows(&f, once, absorption, 100, 50.0);
    }

    #[test]
    fn photon_form_excitation_sampling_follows_wavelength_times_absorption() {
        // The same triangle in the photon form: density ∝ λ·a(λ), compared per 10 nm bin
        // with the exact masses of λ·a (0.01 nm midpoint sums of the triangle itself).
        let grid: Vec<f64> = (0..=481).map(|i| 300.0 + i as f64).collect();
        let fluorophore = crate::material::Fluorophore {
            concentration: 0.5,
            quantum_yield: 0.8,
            yield_form: YieldForm::Photon,
            concentration_range: None,
            absorption: crate::spectrum::Spectrum {
                wavelength_nm: grid.clone(),
                value: grid.iter().map(|&l| triangle(l)).collect(),
            },
            emission: crate::spectrum::Spectrum {
                wavelength_nm: vec![550.0, 650.0],
                value: vec![0.01, 0.01],
            },
        };
        let f = FluorophoreTables::new(&fluorophore);
        // A = ∫λ·a dλ/λ̄e: the triangle's area 50 times its centroid (400 + 430 + 500)/3.
        let centroid = (400.0 + 430.0 + 500.0) / 3.0;
        assert!(
            (f.absorption_integral as f64 - 50.0 * centroid / 600.0).abs() < 1e-4,
            "{}",
            f.absorption_integral
        );
        let mut rng = crate::render::rng::Rng::new(7, 0);
        let density = |nm: f64| nm * triangle(nm);
        assert_excitation_follows(&f, || rng.next_f32(), density, 1000, 50.0 * centroid);
    }

    #[test]
    fn observer_density_integrates_to_one() {
        let o = Observer::get();
        let total: f32 = o.density.iter().sum();
        assert!((total - 1.0).abs() < 1e-4);
        let (nm, p) = o.sample(0.5);
        assert!((360.0..=780.0).contains(&nm) && p > 0.0);
    }
}
