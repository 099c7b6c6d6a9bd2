//! Continuous spectra described by a few parameters: sums of Gaussian bands (absorption,
//! emission) and a sigmoid of a polynomial (reflectance).
//!
//! A form is exact at any wavelength; a material stores it beside its tabulated samples
//! (which render, check and export read) in the `forms` block. The solver works on a raw
//! parameter vector per form ([`GaussianBands::params`], [`SigmoidPolynomial`]'s
//! coefficients) scaled so that a change of order one moves a band by about its width.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::spectrum::Spectrum;

pub mod fit;
mod lm;
pub mod sigmoid_fit;

/// The axis on which bands are Gaussian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum BandDomain {
    /// Gaussian in wavenumber ν = 10⁷/λ (cm⁻¹): the shape of electronic bands.
    Wavenumber,
    /// Gaussian in wavelength (nm).
    Wavelength,
}

impl BandDomain {
    /// The solver coordinate of `nm`: wavenumber in 1000 cm⁻¹ or wavelength in 10 nm.
    pub fn coordinate(self, nm: f64) -> f64 {
        match self {
            BandDomain::Wavenumber => 1.0e4 / nm,
            BandDomain::Wavelength => nm / 10.0,
        }
    }

    /// The wavelength (nm) at solver coordinate `u`.
    pub fn wavelength_nm(self, u: f64) -> f64 {
        match self {
            BandDomain::Wavenumber => 1.0e4 / u,
            BandDomain::Wavelength => u * 10.0,
        }
    }

    /// Factor from solver-coordinate widths to the stored unit (cm⁻¹ or nm).
    pub fn width_unit(self) -> f64 {
        match self {
            BandDomain::Wavenumber => 1000.0,
            BandDomain::Wavelength => 10.0,
        }
    }

    /// The unit of stored band widths.
    pub fn width_unit_name(self) -> &'static str {
        match self {
            BandDomain::Wavenumber => "cm⁻¹",
            BandDomain::Wavelength => "nm",
        }
    }

    /// The name used on the command line and in model names.
    pub fn name(self) -> &'static str {
        match self {
            BandDomain::Wavenumber => "wavenumber",
            BandDomain::Wavelength => "wavelength",
        }
    }
}

/// One Gaussian band: `height · exp(−½((u − centre)/width)²)` in the band domain.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GaussianBand {
    /// Wavelength of the band's centre (nm).
    pub centre_nm: f64,
    /// Standard deviation in the domain's unit (cm⁻¹ for wavenumber, nm for wavelength).
    pub width: f64,
    /// Peak value.
    pub height: f64,
}

/// Parameters per band in the raw vector: ln height, centre coordinate, ln width.
pub const PARAMS_PER_BAND: usize = 3;

/// A sum of Gaussian bands, zero outside `support_nm`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GaussianBands {
    /// The axis the bands are Gaussian in.
    pub domain: BandDomain,
    /// The closed interval (nm) outside which the spectrum is zero.
    pub support_nm: [f64; 2],
    /// The bands.
    pub bands: Vec<GaussianBand>,
}

impl GaussianBands {
    /// The value at `nm` (zero outside the support).
    pub fn eval(&self, nm: f64) -> f64 {
        if !(self.support_nm[0]..=self.support_nm[1]).contains(&nm) {
            return 0.0;
        }
        let unit = self.domain.width_unit();
        let u = self.domain.coordinate(nm);
        self.bands
            .iter()
            .map(|b| {
                let z = (u - self.domain.coordinate(b.centre_nm)) / (b.width / unit);
                b.height * (-0.5 * z * z).exp()
            })
            .sum()
    }

    /// The raw solver vector: per band (ln height, centre coordinate, ln width coordinate).
    pub fn params(&self) -> Vec<f64> {
        let unit = self.domain.width_unit();
        self.bands
            .iter()
            .flat_map(|b| {
                [
                    b.height.max(1e-300).ln(),
                    self.domain.coordinate(b.centre_nm),
                    (b.width / unit).max(1e-300).ln(),
                ]
            })
            .collect()
    }

    /// Bands from a raw solver vector (see [`GaussianBands::params`]).
    pub fn from_params(domain: BandDomain, support_nm: [f64; 2], params: &[f64]) -> Self {
        let unit = domain.width_unit();
        GaussianBands {
            domain,
            support_nm,
            bands: params
                .chunks_exact(PARAMS_PER_BAND)
                .map(|p| GaussianBand {
                    centre_nm: domain.wavelength_nm(p[1]),
                    width: p[2].exp() * unit,
                    height: p[0].exp(),
                })
                .collect(),
        }
    }

    /// Multiplies every band height by `factor` (> 0).
    pub fn scale(&mut self, factor: f64) {
        for b in &mut self.bands {
            b.height *= factor;
        }
    }
}

/// The value of raw band parameters `params` at solver coordinate `u`, ignoring the
/// support, and its derivative with respect to each parameter (written to `gradient`,
/// which must be as long as `params`).
pub fn bands_value_gradient(params: &[f64], u: f64, gradient: &mut [f64]) -> f64 {
    BandTerms::new(params).value_gradient(u, gradient)
}

/// Raw band parameters with each band's height and width taken out of their logarithms
/// once: a fit evaluates every band at every grid sample, and two of the three `exp` per
/// band and sample were these (14 % of a two-component search's time went to `exp`).
/// Per-sample temporaries of [`BandTerms::values_gradients`], kept between calls.
#[derive(Debug, Clone, Default)]
pub struct BandWork {
    z: Vec<f64>,
    v: Vec<f64>,
    by_centre: Vec<f64>,
}

#[derive(Debug, Clone, Default)]
pub struct BandTerms {
    /// Per band: height, centre, width.
    bands: Vec<[f64; 3]>,
}

impl BandTerms {
    /// The terms of raw band parameters `params` (see [`GaussianBands::params`]).
    pub fn new(params: &[f64]) -> Self {
        let mut terms = BandTerms::default();
        terms.set(params);
        terms
    }

    /// Makes these the terms of `params`, reusing their storage (an objective sets them
    /// for every band spectrum of every evaluation).
    pub fn set(&mut self, params: &[f64]) {
        self.bands.clear();
        self.bands.extend(
            params
                .chunks_exact(PARAMS_PER_BAND)
                .map(|p| [p[0].exp(), p[1], p[2].exp()]),
        );
    }

    /// [`BandTerms::value_gradient`] at every abscissa of `u`, bit for bit: the values
    /// into `values`, the derivatives into `jacobian` (one row as long as the parameters
    /// per abscissa). Band by band over all abscissae, so that the divisions vectorise
    /// (only `exp` stays one call per sample and band); each value sums its bands in band
    /// order from 0, as `value_gradient` does. Without bands, both are left empty. `work`
    /// holds the per-sample temporaries.
    pub fn values_gradients(
        &self,
        u: &[f64],
        values: &mut Vec<f64>,
        jacobian: &mut Vec<f64>,
        work: &mut BandWork,
    ) {
        let width = self.bands.len() * PARAMS_PER_BAND;
        values.clear();
        jacobian.clear();
        if width == 0 {
            return;
        }
        values.resize(u.len(), 0.0);
        jacobian.resize(u.len() * width, 0.0);
        let BandWork { z, v, by_centre } = work;
        for (b, &[height, centre, w]) in self.bands.iter().enumerate() {
            z.clear();
            z.extend(u.iter().map(|&u| (u - centre) / w));
            v.clear();
            v.extend(z.iter().map(|&z| height * (-0.5 * z * z).exp()));
            by_centre.clear();
            by_centre.extend(v.iter().zip(z.iter()).map(|(&v, &z)| v * z / w));
            for ((((value, g), &v), &z), &c) in values
                .iter_mut()
                .zip(jacobian.chunks_exact_mut(width))
                .zip(v.iter())
                .zip(z.iter())
                .zip(by_centre.iter())
            {
                *value += v;
                let g = &mut g[PARAMS_PER_BAND * b..PARAMS_PER_BAND * (b + 1)];
                g[0] = v;
                g[1] = c;
                g[2] = v * z * z;
            }
        }
    }

    /// The bands' value at solver coordinate `u`, ignoring the support, and its
    /// derivative with respect to each raw parameter (written to `gradient`, which must
    /// be as long as the parameters).
    pub fn value_gradient(&self, u: f64, gradient: &mut [f64]) -> f64 {
        let mut value = 0.0;
        for (&[height, centre, width], g) in self
            .bands
            .iter()
            .zip(gradient.chunks_exact_mut(PARAMS_PER_BAND))
        {
            let z = (u - centre) / width;
            let v = height * (-0.5 * z * z).exp();
            value += v;
            g[0] = v;
            g[1] = v * z / width;
            g[2] = v * z * z;
        }
        value
    }
}

/// A reflectance `1/(1 + exp(−p(x)))` with p a Legendre series on x ∈ [−1, 1] mapped from
/// `support_nm`. It lies in (0, 1) for any coefficients and holds its end values outside
/// the support (like a tabulated reflectance).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SigmoidPolynomial {
    /// The interval (nm) mapped to x ∈ [−1, 1].
    pub support_nm: [f64; 2],
    /// Legendre coefficients c₀, c₁, … (degree = length − 1).
    pub coefficients: Vec<f64>,
}

impl SigmoidPolynomial {
    /// x ∈ [−1, 1] for `nm` (clamped outside the support).
    pub fn position(&self, nm: f64) -> f64 {
        position(self.support_nm, nm)
    }

    /// The value at `nm`.
    pub fn eval(&self, nm: f64) -> f64 {
        let x = self.position(nm);
        let mut p = 0.0;
        legendre(x, self.coefficients.len(), |n, pn| {
            p += self.coefficients[n] * pn;
        });
        sigmoid(p)
    }

    /// The polynomial degree.
    pub fn degree(&self) -> usize {
        self.coefficients.len().saturating_sub(1)
    }
}

/// x ∈ [−1, 1] for `nm` on `support_nm` (clamped).
pub fn position(support_nm: [f64; 2], nm: f64) -> f64 {
    let span = support_nm[1] - support_nm[0];
    if span <= 0.0 {
        return 0.0;
    }
    (2.0 * (nm - support_nm[0]) / span - 1.0).clamp(-1.0, 1.0)
}

/// Calls `f(n, Pₙ(x))` for the first `count` Legendre polynomials.
pub fn legendre(x: f64, count: usize, mut f: impl FnMut(usize, f64)) {
    let (mut previous, mut current) = (0.0, 1.0);
    for n in 0..count {
        f(n, current);
        // (n + 1)·P_{n+1} = (2n + 1)·x·P_n − n·P_{n−1}
        let next = ((2 * n + 1) as f64 * x * current - n as f64 * previous) / (n + 1) as f64;
        previous = current;
        current = next;
    }
}

/// The logistic function, without overflow for large |p|.
pub fn sigmoid(p: f64) -> f64 {
    if p >= 0.0 {
        1.0 / (1.0 + (-p).exp())
    } else {
        let e = p.exp();
        e / (1.0 + e)
    }
}

/// The inverse of [`sigmoid`] for a value clamped into (ε, 1 − ε).
pub fn logit(value: f64) -> f64 {
    let v = value.clamp(1e-6, 1.0 - 1e-6);
    (v / (1.0 - v)).ln()
}

/// A continuous spectrum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum SpectralForm {
    /// A sum of Gaussian bands.
    GaussianBands(GaussianBands),
    /// A sigmoid of a Legendre polynomial.
    SigmoidPolynomial(SigmoidPolynomial),
}

impl SpectralForm {
    /// The value at `nm`.
    pub fn eval(&self, nm: f64) -> f64 {
        match self {
            SpectralForm::GaussianBands(b) => b.eval(nm),
            SpectralForm::SigmoidPolynomial(s) => s.eval(nm),
        }
    }

    /// Number of free parameters the form has.
    pub fn n_params(&self) -> usize {
        match self {
            SpectralForm::GaussianBands(b) => PARAMS_PER_BAND * b.bands.len(),
            SpectralForm::SigmoidPolynomial(s) => s.coefficients.len(),
        }
    }

    /// The interval the form is defined on (nm).
    pub fn support_nm(&self) -> [f64; 2] {
        match self {
            SpectralForm::GaussianBands(b) => b.support_nm,
            SpectralForm::SigmoidPolynomial(s) => s.support_nm,
        }
    }

    /// How far the form is from the samples (`wavelength_nm`, `value`) it should
    /// reproduce, relative to the samples' peak magnitude; `tolerance` counts the samples
    /// beyond it. None without samples. A non-finite form value is infinitely far.
    pub fn agreement(
        &self,
        wavelength_nm: &[f64],
        value: &[f64],
        tolerance: f64,
    ) -> Option<FormAgreement> {
        let peak = value.iter().fold(0.0f64, |p, v| p.max(v.abs())).max(1e-300);
        let mut agreement: Option<FormAgreement> = None;
        let mut beyond = 0;
        for (&l, &v) in wavelength_nm.iter().zip(value) {
            let f = self.eval(l);
            let deviation = (f - v).abs() / peak;
            let deviation = if deviation.is_nan() {
                f64::INFINITY
            } else {
                deviation
            };
            if deviation > tolerance {
                beyond += 1;
            }
            if agreement.as_ref().is_none_or(|a| deviation > a.worst) {
                agreement = Some(FormAgreement {
                    worst: deviation,
                    at_nm: l,
                    form_value: f,
                    sample: v,
                    beyond: 0,
                });
            }
        }
        agreement.map(|a| FormAgreement { beyond, ..a })
    }

    /// Samples on `grid` (nm); `what` names the spectrum in errors.
    pub fn tabulate(&self, grid: &[f64], what: &str) -> Result<Spectrum> {
        Spectrum::new(
            grid.to_vec(),
            grid.iter().map(|&l| self.eval(l)).collect(),
            what,
        )
    }

    /// Checks that every number is finite and the support is an interval.
    pub fn validate(&self, what: &str) -> Result<()> {
        let [lo, hi] = self.support_nm();
        if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo > 0.0) {
            return Err(Error::invalid(
                format!("{what}.support_nm"),
                format!("is [{lo}, {hi}]; give two increasing positive wavelengths"),
            ));
        }
        let bad = match self {
            SpectralForm::GaussianBands(b) => b
                .bands
                .iter()
                .position(|b| {
                    let positive = |v: f64| v.is_finite() && v > 0.0;
                    !(positive(b.centre_nm)
                        && positive(b.width)
                        && b.height.is_finite()
                        && b.height >= 0.0)
                })
                .map(|n| format!("{what}.bands[{n}]")),
            SpectralForm::SigmoidPolynomial(s) => s
                .coefficients
                .iter()
                .position(|c| !c.is_finite())
                .map(|n| format!("{what}.coefficients[{n}]")),
        };
        match bad {
            Some(place) => Err(Error::invalid(
                place,
                "has a non-finite or out-of-range number; centres and widths must be positive, heights non-negative",
            )),
            None => Ok(()),
        }
    }
}

/// Continuous forms of a material's spectra (the `forms` block of a material): the
/// tabulated samples beside them are these forms evaluated on a fine grid.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaterialForms {
    /// The model's name (`gaussian:1x2`, …).
    pub model: String,
    /// r(λ), if it is a form (absent when the reflectance is tabulated).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reflectance: Option<SpectralForm>,
    /// a(λ) and e(λ) per fluorophore, in the order of the material's fluorophores.
    pub fluorophores: Vec<FluorophoreForms>,
}

/// How far a form is from its samples ([`SpectralForm::agreement`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FormAgreement {
    /// The largest |form − sample| relative to the samples' peak magnitude.
    pub worst: f64,
    /// Where it is (nm).
    pub at_nm: f64,
    /// The form's value there.
    pub form_value: f64,
    /// The sample there.
    pub sample: f64,
    /// Samples farther than the tolerance.
    pub beyond: usize,
}

impl MaterialForms {
    /// Each form beside the tabulated spectrum it describes and its place in the file
    /// (`reflectance`, `fluorophores[0].absorption`, …): the reflectance, then absorption
    /// and emission per fluorophore, in order. `fluorophores` gives (absorption,
    /// emission) per fluorophore; extra entries on either side are left out.
    pub fn pairs<'a, S>(
        &'a self,
        reflectance: &'a S,
        fluorophores: impl IntoIterator<Item = (&'a S, &'a S)>,
    ) -> Vec<(&'a SpectralForm, &'a S, String)> {
        let mut pairs = Vec::new();
        if let Some(r) = &self.reflectance {
            pairs.push((r, reflectance, "reflectance".to_string()));
        }
        for (n, (forms, (absorption, emission))) in
            self.fluorophores.iter().zip(fluorophores).enumerate()
        {
            pairs.push((
                &forms.absorption,
                absorption,
                format!("fluorophores[{n}].absorption"),
            ));
            pairs.push((
                &forms.emission,
                emission,
                format!("fluorophores[{n}].emission"),
            ));
        }
        pairs
    }
}

/// The forms of one fluorophore: evaluated, they equal its tabulated spectra (a with
/// max 1, e with ∫e = 1 over its support).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FluorophoreForms {
    /// a(λ).
    pub absorption: SpectralForm,
    /// e(λ) in 1/nm.
    pub emission: SpectralForm,
}

/// Checks that `nm` and `values` are usable samples: as many of each, at least
/// `min_samples`, finite, wavelengths positive and strictly increasing.
pub(crate) fn check_samples(nm: &[f64], values: &[f64], min_samples: usize) -> Result<()> {
    if nm.len() != values.len() {
        return Err(Error::invalid(
            "values",
            format!(
                "has {} samples but nm has {}; give one value per wavelength",
                values.len(),
                nm.len()
            ),
        ));
    }
    if nm.len() < min_samples.max(1) {
        return Err(Error::invalid(
            "nm",
            format!(
                "has {} samples; this fit needs at least {}",
                nm.len(),
                min_samples.max(1)
            ),
        ));
    }
    for (i, &l) in nm.iter().enumerate() {
        if !(l.is_finite() && l > 0.0) {
            return Err(Error::invalid(
                format!("nm[{i}]"),
                format!("is {l}; wavelengths must be positive finite numbers (nm)"),
            ));
        }
        if i > 0 && l <= nm[i - 1] {
            return Err(Error::invalid(
                format!("nm[{i}]"),
                format!(
                    "is {l} nm, not above the previous sample's {} nm; sort the samples by wavelength and drop duplicates",
                    nm[i - 1]
                ),
            ));
        }
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Error::invalid(
            format!("values[{i}]"),
            format!(
                "is {}; values must be finite (drop missing samples)",
                values[i]
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_gradient_matches_differences() {
        let params = [0.3, 20.0, 0.1, -0.5, 22.5, -0.4];
        let u = 21.3;
        let mut g = [0.0; 6];
        let v = bands_value_gradient(&params, u, &mut g);
        for k in 0..6 {
            let mut p = params;
            p[k] += 1e-6;
            let mut scratch = [0.0; 6];
            let v2 = bands_value_gradient(&p, u, &mut scratch);
            assert!(((v2 - v) / 1e-6 - g[k]).abs() < 1e-5 * (1.0 + g[k].abs()));
        }
        let bands = GaussianBands::from_params(BandDomain::Wavenumber, [200.0, 900.0], &params);
        let nm = BandDomain::Wavenumber.wavelength_nm(u);
        assert!((bands.eval(nm) - v).abs() < 1e-12);
        let back = bands.params();
        for (a, b) in back.iter().zip(&params) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn band_values_over_a_grid_are_each_samples_value_gradient_bit_for_bit() {
        // Three bands, one narrow enough that most samples sit in its far tail (exp
        // underflows there), on a grid that crosses every centre; the reference is the
        // one-sample form the solvers' bits were built on.
        let params = [0.3, 20.0, 0.1, -0.5, 22.5, -0.4, 1.2, 24.0, -3.0];
        let terms = BandTerms::new(&params);
        let u: Vec<f64> = (0..53).map(|n| 17.0 + 0.17 * n as f64).collect();
        let (mut values, mut jacobian, mut work) = (Vec::new(), Vec::new(), BandWork::default());
        // Twice, the second time over the first call's buffers.
        for _ in 0..2 {
            terms.values_gradients(&u, &mut values, &mut jacobian, &mut work);
            assert_eq!(values.len(), u.len());
            for ((&u, value), row) in u.iter().zip(&values).zip(jacobian.chunks_exact(9)) {
                let mut g = [f64::NAN; 9];
                let v = terms.value_gradient(u, &mut g);
                assert_eq!(value.to_bits(), v.to_bits(), "u {u}");
                assert!(
                    row.iter().zip(&g).all(|(a, b)| a.to_bits() == b.to_bits()),
                    "u {u}"
                );
            }
        }
        assert!(values.iter().any(|&v| v > 1.0) && jacobian.contains(&0.0));
        // Without bands, nothing (as the one-sample form gives no row either).
        BandTerms::new(&[]).values_gradients(&u, &mut values, &mut jacobian, &mut work);
        assert!(values.is_empty() && jacobian.is_empty());
    }

    #[test]
    fn legendre_matches_closed_forms() {
        let x = 0.37;
        let mut p = Vec::new();
        legendre(x, 4, |_, v| p.push(v));
        assert!((p[2] - 0.5 * (3.0 * x * x - 1.0)).abs() < 1e-15);
        assert!((p[3] - 0.5 * (5.0 * x * x * x - 3.0 * x)).abs() < 1e-15);
    }

    #[test]
    fn sigmoid_polynomial_stays_in_range_and_holds_ends() {
        let s = SigmoidPolynomial {
            support_nm: [380.0, 780.0],
            coefficients: vec![40.0, -80.0, 15.0],
        };
        for nm in [300.0, 380.0, 500.0, 780.0, 900.0] {
            let v = s.eval(nm);
            assert!((0.0..=1.0).contains(&v), "{v}");
        }
        assert_eq!(s.eval(300.0), s.eval(380.0));
        assert!((logit(sigmoid(0.7)) - 0.7).abs() < 1e-12);
    }

    #[test]
    fn forms_round_trip_through_json() {
        let form = SpectralForm::GaussianBands(GaussianBands {
            domain: BandDomain::Wavenumber,
            support_nm: [300.0, 780.0],
            bands: vec![GaussianBand {
                centre_nm: 490.0,
                width: 1200.0,
                height: 1.0,
            }],
        });
        let json = serde_json::to_string(&form).unwrap();
        assert!(json.contains("\"kind\":\"gaussian-bands\""), "{json}");
        let back: SpectralForm = serde_json::from_str(&json).unwrap();
        assert_eq!(back, form);
        assert!((form.eval(490.0) - 1.0).abs() < 1e-12);
        assert_eq!(form.eval(299.0), 0.0);
    }

    #[test]
    fn agreement_measures_the_worst_sample_against_the_peak() {
        let form = SpectralForm::SigmoidPolynomial(SigmoidPolynomial {
            support_nm: [380.0, 780.0],
            coefficients: vec![0.5, 1.0],
        });
        let nm: Vec<f64> = (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect();
        let mut value: Vec<f64> = nm.iter().map(|&l| form.eval(l)).collect();
        let exact = form.agreement(&nm, &value, 1e-6).unwrap();
        assert_eq!((exact.worst, exact.beyond), (0.0, 0));
        let peak = value.iter().cloned().fold(0.0, f64::max);
        value[7] += 0.01 * peak;
        value[30] -= 0.002 * peak;
        let off = form.agreement(&nm, &value, 1e-3).unwrap();
        assert!((off.worst - 0.01).abs() < 1e-9, "{off:?}");
        assert_eq!((off.at_nm, off.beyond), (450.0, 2));
        assert_eq!(off.sample, value[7]);
        // A form that evaluates to NaN is infinitely far, never within tolerance.
        let broken = SpectralForm::SigmoidPolynomial(SigmoidPolynomial {
            support_nm: [380.0, 780.0],
            coefficients: vec![f64::NAN],
        });
        let nan = broken.agreement(&nm, &value, 1e-6).unwrap();
        assert!(nan.worst.is_infinite() && nan.beyond == nm.len());
        assert!(form.agreement(&[], &[], 1e-6).is_none());
    }
}
