//! Joint fits of sets of EEMs: K fluorophores whose absorption (excitation) and emission
//! shapes all samples share, one non-negative score per sample and component — the
//! non-negative PARAFAC spectroscopists fit with drEEM, staRdom or tensorly, with this
//! project's normalisations (max a = 1, ∫e dλ = 1; the scores carry the scale) and one
//! closed-form start ([`parafac`]).

pub mod diagnostics;
pub mod parafac;
pub mod reference;
pub mod scatter;

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::material::{FitReport, FluorophoreShapes, SHAPES_SCHEMA};
use crate::measurement::Measurement;
use crate::spectrum::{Spectrum, bin_widths};
use diagnostics::{SplitHalf, core_consistency, split_half};
use parafac::image::Image;
use parafac::{Factors, ParafacOptions, Tensor, fit_with_image};

/// Schema tag of a joint model file.
pub const JOINT_SCHEMA: &str = "fluorite-parafac/1";

/// How to fit a set jointly.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointOptions {
    /// Components and iteration control.
    pub parafac: ParafacOptions,
    /// Emission range kept (nm, inclusive); `None` = all.
    pub em_range: Option<(f64, f64)>,
    /// Excitation range kept (nm, inclusive); `None` = all.
    pub ex_range: Option<(f64, f64)>,
    /// Skip the split-half validation (it fits both halves again).
    pub no_split_half: bool,
    /// Fit the grating's second-order image of the emission: each component seen as
    /// `e(λo) + G(λo)·e(λo/2)`, G shared ([`parafac::image`]); the components' emission
    /// is then first-order only. Ignored when no emission wavelength has its half on the
    /// grid.
    pub second_order: bool,
}

/// The fitted second-order image: the data see each component's first-order emission e
/// as `e(λo) + G(λo)·e(λo/2)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SecondOrderImage {
    /// G's nodes (nm); G is linear between them and zero outside.
    pub wavelength_nm: Vec<f64>,
    /// G at the nodes (≥ 0).
    pub gain: Vec<f64>,
}

/// One component: shapes shared by every sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointComponent {
    /// a(λ) on the excitation grid, max 1.
    pub absorption: Spectrum,
    /// e(λ) on the emission grid, ∫e = 1 (1/nm).
    pub emission: Spectrum,
    /// Wavelength of the absorption maximum (nm).
    pub peak_excitation_nm: f64,
    /// Wavelength of the emission maximum (nm).
    pub peak_emission_nm: f64,
    /// Share of the model's sum of squares this component carries.
    pub share: f64,
    /// How much of the emission lies inside the set's scatter bands at the excitation
    /// maximum ([`JointFit::check_scatter`]); absent until checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scatter: Option<scatter::ScatterOverlap>,
    /// With the second-order image fitted: the share of the component's signal over the
    /// emission grid (∫ of `e + G·e(λo/2)`) that is its image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_share: Option<f64>,
}

/// A joint fit of a sample set and how good it is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointFit {
    /// Always [`JOINT_SCHEMA`].
    pub schema: String,
    /// Sample names (file stems), in input order.
    pub samples: Vec<String>,
    /// Their files.
    pub sources: Vec<String>,
    /// The components, largest share first.
    pub components: Vec<JointComponent>,
    /// `scores[sample][component]`, in the data's (arbitrary) units.
    pub scores: Vec<Vec<f64>>,
    /// 1 − Σ residual² / Σ data² over the measured cells (uncentred, as drEEM reports).
    pub explained_variance: f64,
    /// Core consistency in per cent (Bro & Kiers 2003).
    pub core_consistency: f64,
    /// Split-half validation; absent when skipped or with fewer than four samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub split_half: Option<SplitHalf>,
    /// RMS residual relative to the RMS data, over each sample's measured cells.
    pub residual_per_sample: Vec<f64>,
    /// Cells fitted (measured) and cells missing (not recorded or scatter masked).
    pub measured_cells: usize,
    /// Missing cells (not recorded, or masked as scatter).
    pub missing_cells: usize,
    /// ALS sweeps.
    pub iterations: usize,
    /// Whether the loss change fell below the tolerance.
    pub converged: bool,
    /// Wall time of the fit alone (seconds).
    pub seconds: f64,
    /// Wall time of core consistency and split-half validation (seconds).
    pub diagnostics_seconds: f64,
    /// The second-order image, when fitted ([`JointOptions::second_order`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_order: Option<SecondOrderImage>,
    /// Why the fit holds no second-order image where the data seemed to ask for one
    /// (`--second-order auto` found it carrying nothing and fitted without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_order_note: Option<String>,
}

/// Crops every matrix to the ranges and stacks them; all must share the cropped grids.
/// Returns the tensor and its excitation and emission grids.
pub fn stack(
    measurements: &[Measurement],
    options: &JointOptions,
) -> Result<(Tensor, Vec<f64>, Vec<f64>)> {
    let Some(first) = measurements.first() else {
        return Err(Error::invalid(
            "joint fit",
            "no samples: give the EEM files of the set",
        ));
    };
    let keep = |grid: &[f64], range: Option<(f64, f64)>| -> Vec<usize> {
        (0..grid.len())
            .filter(|&i| range.is_none_or(|(lo, hi)| grid[i] >= lo - 1e-9 && grid[i] <= hi + 1e-9))
            .collect()
    };
    let ex_keep = keep(&first.excitation_nm, options.ex_range);
    let em_keep = keep(&first.emission_nm, options.em_range);
    let pick = |grid: &[f64], idx: &[usize]| idx.iter().map(|&i| grid[i]).collect::<Vec<f64>>();
    let ex_nm = pick(&first.excitation_nm, &ex_keep);
    let em_nm = pick(&first.emission_nm, &em_keep);
    if ex_nm.is_empty() || em_nm.len() < 2 {
        return Err(Error::invalid(
            if ex_nm.is_empty() {
                "--ex-range"
            } else {
                "--em-range"
            },
            format!(
                "keeps no cells of {} (excitation {}–{} nm, emission {}–{} nm); widen the range",
                first.name,
                first.excitation_nm[0],
                first.excitation_nm[first.n_excitation() - 1],
                first.emission_nm[0],
                first.emission_nm[first.n_emission() - 1]
            ),
        ));
    }
    let mut values = Vec::with_capacity(measurements.len() * ex_nm.len() * em_nm.len());
    for m in measurements {
        let ex_i = keep(&m.excitation_nm, options.ex_range);
        let em_i = keep(&m.emission_nm, options.em_range);
        let same = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
        };
        if !same(&pick(&m.excitation_nm, &ex_i), &ex_nm)
            || !same(&pick(&m.emission_nm, &em_i), &em_nm)
        {
            return Err(Error::invalid(
                "joint fit",
                format!(
                    "{}: its grids (excitation {} wavelengths, emission {}) differ from {}'s after cropping (excitation {} at {}–{} nm, emission {} at {}–{} nm); a joint fit needs every sample on one grid: measure them with the same settings or crop with --ex-range/--em-range",
                    source_of(m),
                    ex_i.len(),
                    em_i.len(),
                    source_of(first),
                    ex_nm.len(),
                    ex_nm[0],
                    ex_nm[ex_nm.len() - 1],
                    em_nm.len(),
                    em_nm[0],
                    em_nm[em_nm.len() - 1]
                ),
            ));
        }
        for &i in &ex_i {
            for &j in &em_i {
                values.push(m.get(i, j));
            }
        }
    }
    let t = Tensor {
        samples: measurements.len(),
        n_ex: ex_nm.len(),
        n_em: em_nm.len(),
        values,
    };
    Ok((t, ex_nm, em_nm))
}

fn source_of(m: &Measurement) -> String {
    m.source
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| m.name.clone())
}

/// Fits the set jointly (see the module doc) and judges the model.
pub fn fit_joint(measurements: &[Measurement], options: &JointOptions) -> Result<JointFit> {
    let (t, ex_nm, em_nm) = stack(measurements, options)?;
    let k = options.parafac.components;
    let measured_cells = t.values.iter().filter(|v| v.is_finite()).count();
    if measured_cells < k * (t.samples + t.n_ex + t.n_em) {
        return Err(Error::invalid(
            "--components",
            format!(
                "{k} components need at least {} measured cells, the set holds {measured_cells}; fit fewer components or give more samples",
                k * (t.samples + t.n_ex + t.n_em)
            ),
        ));
    }
    let weights = bin_widths(&em_nm);
    let image = if options.second_order {
        Image::new(&em_nm)
    } else {
        None
    };
    let started = Instant::now();
    let model = fit_with_image(&t, &weights, &options.parafac, image.as_ref())?;
    let seconds = started.elapsed().as_secs_f64();
    let mut factors = ordered(&model.factors, &t);
    // With the image: the effective emission rescaled so that its first-order part has
    // ∫e = 1 (the scores take the scale), and the first-order parts for the report.
    let mut first_order = factors.emission.clone();
    let mut image_shares = vec![None; k];
    let mut second_order = None;
    if let (Some(image), Some(g)) = (&image, &model.image_gain) {
        let gain = image.gain(g);
        for (c, image_share) in image_shares.iter_mut().enumerate() {
            let range = c * t.n_em..(c + 1) * t.n_em;
            let e = image.first_order(&factors.emission[range.clone()], &gain);
            let area = crate::numeric::dot(&e, &weights);
            let total = crate::numeric::dot(&factors.emission[range.clone()], &weights);
            if area > 0.0 {
                for s in 0..t.samples {
                    factors.scores[s * k + c] *= area;
                }
                factors.emission[range.clone()]
                    .iter_mut()
                    .for_each(|v| *v /= area);
                first_order[range.clone()]
                    .iter_mut()
                    .zip(&e)
                    .for_each(|(o, v)| *o = v / area);
            }
            if total > 0.0 {
                *image_share = Some((1.0 - area / total).clamp(0.0, 1.0));
            }
        }
        second_order = Some(SecondOrderImage {
            wavelength_nm: image.nodes_nm().to_vec(),
            gain: g.clone(),
        });
    }
    let started = Instant::now();
    let core = core_consistency(&t, &factors);
    let halves = if options.no_split_half {
        None
    } else {
        split_half(&t, &weights, &options.parafac, image.as_ref())?
    };
    let diagnostics_seconds = started.elapsed().as_secs_f64();
    let (mut total, mut residual) = (0.0, 0.0);
    let mut residual_per_sample = Vec::with_capacity(t.samples);
    for s in 0..t.samples {
        let (mut data, mut misfit) = (0.0, 0.0);
        for ex in 0..t.n_ex {
            for em in 0..t.n_em {
                let v = t.values[t.index(s, ex, em)];
                if v.is_finite() {
                    data += v * v;
                    misfit += (v - factors.model(&t, s, ex, em)).powi(2);
                }
            }
        }
        total += data;
        residual += misfit;
        residual_per_sample.push(if data > 0.0 {
            (misfit / data).sqrt()
        } else {
            0.0
        });
    }
    let shares = component_shares(&factors, &t);
    let components = (0..k)
        .map(|c| {
            let absorption = factors.excitation[c * t.n_ex..(c + 1) * t.n_ex].to_vec();
            let emission = first_order[c * t.n_em..(c + 1) * t.n_em].to_vec();
            JointComponent {
                peak_excitation_nm: ex_nm[argmax(&absorption)],
                peak_emission_nm: em_nm[argmax(&emission)],
                absorption: Spectrum {
                    wavelength_nm: ex_nm.clone(),
                    value: absorption,
                },
                emission: Spectrum {
                    wavelength_nm: em_nm.clone(),
                    value: emission,
                },
                share: shares[c],
                scatter: None,
                image_share: image_shares[c],
            }
        })
        .collect();
    Ok(JointFit {
        schema: JOINT_SCHEMA.into(),
        samples: measurements.iter().map(|m| m.name.clone()).collect(),
        sources: measurements.iter().map(source_of).collect(),
        components,
        scores: (0..t.samples)
            .map(|s| factors.scores[s * k..(s + 1) * k].to_vec())
            .collect(),
        explained_variance: if total > 0.0 {
            1.0 - residual / total
        } else {
            0.0
        },
        core_consistency: core,
        split_half: halves,
        residual_per_sample,
        measured_cells,
        missing_cells: t.values.len() - measured_cells,
        iterations: model.iterations,
        converged: model.converged,
        seconds,
        diagnostics_seconds,
        second_order,
        second_order_note: None,
    })
}

fn argmax(v: &[f64]) -> usize {
    (0..v.len())
        .max_by(|&a, &b| v[a].total_cmp(&v[b]))
        .unwrap_or(0)
}

/// Each component's share of the model's (unmasked) sum of squares.
fn component_shares(f: &Factors, t: &Tensor) -> Vec<f64> {
    let k = f.k;
    let size: Vec<f64> = (0..k)
        .map(|c| {
            let a: f64 = (0..t.samples).map(|s| f.scores[s * k + c].powi(2)).sum();
            let x = crate::numeric::dot(
                &f.excitation[c * t.n_ex..(c + 1) * t.n_ex],
                &f.excitation[c * t.n_ex..(c + 1) * t.n_ex],
            );
            let e = crate::numeric::dot(
                &f.emission[c * t.n_em..(c + 1) * t.n_em],
                &f.emission[c * t.n_em..(c + 1) * t.n_em],
            );
            a * x * e
        })
        .collect();
    let total: f64 = size.iter().sum();
    size.iter()
        .map(|v| if total > 0.0 { v / total } else { 0.0 })
        .collect()
}

/// The factors with components reordered by share, largest first (ties by the
/// emission maximum), so the output does not depend on the start's order.
fn ordered(f: &Factors, t: &Tensor) -> Factors {
    let k = f.k;
    let shares = component_shares(f, t);
    let mut order: Vec<usize> = (0..k).collect();
    order.sort_by(|&a, &b| shares[b].total_cmp(&shares[a]));
    let mut out = f.clone();
    for (new, &old) in order.iter().enumerate() {
        for s in 0..t.samples {
            out.scores[s * k + new] = f.scores[s * k + old];
        }
        out.excitation[new * t.n_ex..(new + 1) * t.n_ex]
            .copy_from_slice(&f.excitation[old * t.n_ex..(old + 1) * t.n_ex]);
        out.emission[new * t.n_em..(new + 1) * t.n_em]
            .copy_from_slice(&f.emission[old * t.n_em..(old + 1) * t.n_em]);
    }
    out
}

impl JointFit {
    /// Measures, per component, the share of its emission inside `bands` (the set's scatter
    /// bands, [`scatter::set_bands`]) at its excitation maximum, with the Raman shift
    /// `raman_shift_cm` (`None`: water's), into [`JointComponent::scatter`].
    pub fn check_scatter(
        &mut self,
        bands: &[crate::eem::scatter::MaskedBand],
        raman_shift_cm: Option<f64>,
    ) {
        for c in &mut self.components {
            c.scatter = Some(scatter::overlap(c, bands, raman_shift_cm));
        }
    }

    /// Pretty JSON of the whole model.
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("joint fit serialises");
        s.push('\n');
        s
    }

    /// The files a joint fit writes into `dir`, as (path, bytes): `model.json` (this fit),
    /// `scores.csv` and one fluorophore per component, `component-<k>.json` (1-based).
    /// Figures (`plot::joint`) join them before all are written at once.
    pub fn files(&self, dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
        let mut files = vec![
            (dir.join("model.json"), self.to_json().into_bytes()),
            (dir.join("scores.csv"), self.scores_csv().into_bytes()),
        ];
        for c in 0..self.components.len() {
            files.push((
                dir.join(format!("component-{}.json", c + 1)),
                self.fluorophore(c).to_json().into_bytes(),
            ));
        }
        files
    }

    /// The score table: one row per sample, one column per component.
    pub fn scores_csv(&self) -> String {
        let mut out = String::from("sample");
        for c in 1..=self.components.len() {
            out.push_str(&format!(",component_{c}"));
        }
        out.push_str(",residual_rms_relative\n");
        for ((name, row), r) in self
            .samples
            .iter()
            .zip(&self.scores)
            .zip(&self.residual_per_sample)
        {
            out.push_str(name);
            for v in row {
                out.push_str(&format!(",{v:.6e}"));
            }
            out.push_str(&format!(",{r:.6}\n"));
        }
        out
    }

    /// Component `c` (< the number of components) as a `fluorite-fluorophore/1` file,
    /// as single EEM fits write (shapes only; the per-sample scale is in the score
    /// table).
    pub fn fluorophore(&self, c: usize) -> FluorophoreShapes {
        let component = &self.components[c];
        let mean_score =
            self.scores.iter().map(|r| r[c]).sum::<f64>() / self.scores.len().max(1) as f64;
        let undetermined = vec![
            "reflectance r(λ): solution EEMs have no diagonal".to_string(),
            "concentration c and quantum yield Q separately: each sample's score is c·Q on the data's arbitrary scale (see the score table)".to_string(),
        ];
        FluorophoreShapes {
            schema: SHAPES_SCHEMA.into(),
            name: format!("component {} of {}", c + 1, self.components.len()),
            absorption: component.absorption.clone(),
            emission: component.emission.clone(),
            k: None,
            k_data_units: mean_score,
            undetermined: undetermined.clone(),
            fit: FitReport {
                source: self.sources.join(", "),
                solver: "non-negative PARAFAC (HALS, closed-form start)".into(),
                converged: self.converged,
                iterations: self.iterations as u64,
                seconds: self.seconds,
                gauge: "none: max a = 1, ∫e = 1, the scores carry the scale".into(),
                rel_residual_fluorescence: (1.0 - self.explained_variance).max(0.0).sqrt(),
                undetermined,
                model: format!("parafac:{}", self.components.len()),
                ..FitReport::default()
            },
        }
    }
}
