//! Where the search's candidates start: the grid fit's spectra fitted with bands, the
//! embedding of a smaller model's optimum, the other yield form's optimum, and the
//! seeds of a second component.

use super::*;
use std::sync::Mutex;
use std::sync::{Arc, OnceLock};

/// θ of the smaller model `small` (parameters `theta`) in `problem`'s layout, which
/// contains it: components, bands and reflectance coefficients copied (a higher degree
/// padded with zeros), each extra band a copy of its component's first band at `extra`
/// times its height, each extra component a copy of the first at κ = 0 (`extra` = 0) or
/// left to the caller (`extra` > 0: κ stays 0 here).
pub(super) fn embed(
    problem: &Problem<'_>,
    small: &ModelSpec,
    theta: &[f64],
    extra: f64,
) -> Vec<f64> {
    let layout = problem.layout;
    let spec = layout.spec;
    let from = crate::fit::parametric::Layout::new(*small);
    let mut out = vec![0.0; layout.len];
    let ln_extra = if extra > 0.0 { extra.ln() } else { -1e3 };
    let copy_bands = |out: &mut [f64], source: &[f64]| {
        let first = &source[..PARAMS_PER_BAND.min(source.len())];
        let top = source
            .chunks_exact(PARAMS_PER_BAND)
            .map(|b| b[0])
            .fold(f64::NEG_INFINITY, f64::max);
        for (n, chunk) in out.chunks_exact_mut(PARAMS_PER_BAND).enumerate() {
            let start = n * PARAMS_PER_BAND;
            if start + PARAMS_PER_BAND <= source.len() {
                chunk.copy_from_slice(&source[start..start + PARAMS_PER_BAND]);
            } else if first.len() == PARAMS_PER_BAND {
                chunk.copy_from_slice(first);
                // The box floor of ln height is −30: e^−30 is zero to the data.
                chunk[0] = (top + ln_extra).max(EMBED_FLOOR);
            }
        }
    };
    for k in 0..spec.components {
        let source = k.min(small.components - 1);
        out[k] = if k < small.components {
            theta[source]
        } else {
            0.0
        };
        copy_bands(
            &mut out[layout.absorption(k)],
            &theta[from.absorption(source)],
        );
        copy_bands(&mut out[layout.emission(k)], &theta[from.emission(source)]);
    }
    let (target, source) = (layout.reflectance(), from.reflectance());
    for (o, t) in out[target].iter_mut().zip(&theta[source]) {
        *o = *t;
    }
    // An added component's free heights at their gauge (grid peak of a and Σe·Δλ at 1),
    // so its gauge terms add nothing to the objective either.
    if spec.components > small.components {
        let gm = problem.grid_model(&out);
        for k in small.components..spec.components {
            let (peak, normaliser) = (gm.absorption_peak[k], gm.normaliser[k]);
            // (Bands at the height floor stay there: below it the box would cost.)
            for band in layout.absorption(k).step_by(PARAMS_PER_BAND) {
                if out[band] > EMBED_FLOOR {
                    out[band] -= peak.max(1e-300).ln();
                }
            }
            for band in layout.emission(k).step_by(PARAMS_PER_BAND) {
                if out[band] > EMBED_FLOOR {
                    out[band] -= normaliser.max(1e-300).ln();
                }
            }
        }
    }
    out
}

/// The nested start: the best smaller model's optimum with extra bands at
/// [`NESTED_EXTRA`] of their component's height and extra components from what it leaves
/// unexplained (weighted as the parent start's), small.
pub(super) fn nested_start(
    problem: &Problem<'_>,
    ctx: &CandidateContext<'_>,
    nested: &Fitted,
) -> Result<Vec<f64>> {
    let layout = problem.layout;
    let spec = layout.spec;
    let mut theta = embed(problem, &nested.spec, &nested.theta, NESTED_EXTRA);
    if spec.components > nested.spec.components {
        let existing = (nested.spec, nested.theta.clone());
        let components = split_components(problem, ctx, Some(&existing), Start::Parent);
        let small = Problem::new(problem.data, nested.spec, &[], &[], 0.0);
        let gm = small.grid_model(&nested.theta);
        let taken: Vec<f64> = (0..problem.data.n_excitation())
            .map(|i| {
                (0..gm.kappa.len())
                    .map(|k| gm.kappa[k] * gm.absorption[k][i] * gm.cap_factor[k][i])
                    .sum()
            })
            .collect();
        let largest = gm.kappa.iter().cloned().fold(0.0, f64::max);
        for (k, (kappa, absorption, emission)) in
            components.iter().enumerate().skip(nested.spec.components)
        {
            let room = room(absorption, &taken);
            let kappa = kappa.min(EXTRA_COMPONENT_SHARE * largest).min(0.9 * room);
            set_component(problem, ctx, &mut theta, k, kappa, absorption, emission)?;
        }
    }
    problem.clamp_to_box(&mut theta);
    Ok(theta)
}

/// How large an added component's c·a may grow where it absorbs (a > 1e-3) before the
/// fluorophores, `taken` (Σc·a) already, absorb all the light.
fn room(absorption: &[f64], taken: &[f64]) -> f64 {
    absorption
        .iter()
        .zip(taken)
        .filter(|(a, _)| **a > 1e-3)
        .map(|(a, t)| (1.0 - t).max(0.0) / a)
        .fold(1.0, f64::min)
}

/// Component `k` of `theta` from its κ and its absorption and emission on the data's
/// grids, with bands fitted to them.
fn set_component(
    problem: &Problem<'_>,
    ctx: &CandidateContext<'_>,
    theta: &mut [f64],
    k: usize,
    kappa: f64,
    absorption: &[f64],
    emission: &[f64],
) -> Result<()> {
    let (data, layout) = (problem.data, problem.layout);
    let spec = layout.spec;
    theta[k] = kappa.clamp(1e-6, START_KAPPA_CAP).sqrt().asin();
    let a = ctx.start_cache.bands(
        &data.excitation_nm,
        absorption,
        spec.domain,
        spec.absorption_bands,
    )?;
    theta[layout.absorption(k)].copy_from_slice(&problem.absorption_solver_params(&a));
    let e = ctx.start_cache.bands(
        &data.emission_nm,
        emission,
        spec.domain,
        spec.emission_bands,
    )?;
    theta[layout.emission(k)].copy_from_slice(&problem.emission_solver_params(&e));
    Ok(())
}

/// The optimum `theta` of the same structure in the other yield form, as a start in
/// `problem`'s: shapes and reflectance copied, each κ rescaled so that the component's
/// fluorescence is unchanged at its absorption peak (energy form: k = κ/γ, photon
/// form: k·λpeak/λ̄e = κ·λpeak/λ̄e).
// Several per-component arrays of the grid model are read by the same index.
#[allow(clippy::needless_range_loop)]
pub(super) fn convert_yield_form(
    problem: &Problem<'_>,
    from: &ModelSpec,
    theta: &[f64],
) -> Vec<f64> {
    let source = Problem::new(problem.data, *from, &[], &[], 0.0);
    let gm = source.grid_model(theta);
    let mut out = theta.to_vec();
    let to_photon = problem.layout.spec.yield_form == YieldForm::Photon;
    for k in 0..gm.kappa.len() {
        let peak_nm = problem.data.excitation_nm[gm.peak_index[k]];
        let mean = gm.emission_mean_nm[k];
        // Fluorescence at the peak per unit emission: s·x (energy x = 1, photon λ/λ̄e).
        let strength = gm.scale[k] * gm.excitation_factor[k][gm.peak_index[k]];
        let kappa = if to_photon {
            strength * gm.normaliser[k] * mean / peak_nm
        } else {
            let shortest = gm.shortest_absorbed_nm[k];
            strength * gm.normaliser[k] * (mean / shortest).max(1.0)
        };
        out[k] = kappa.clamp(1e-6, START_KAPPA_CAP).sqrt().asin();
    }
    problem.clamp_to_box(&mut out);
    out
}

/// How much light the light the tabulated fit matches worst (largest ΔE2000) sends to
/// each excitation row, relative to its peak: the rows whose missing emission the eye
/// sees. All ones without lights.
pub(super) fn worst_light_reach(
    delta_e: &std::collections::BTreeMap<String, f64>,
    lights: &[crate::colour::Light],
    data: &FitData,
) -> Vec<f64> {
    let worst = lights.iter().max_by(|a, b| {
        let de = |l: &crate::colour::Light| delta_e.get(&l.name).copied().unwrap_or(0.0);
        de(a).total_cmp(&de(b))
    });
    let Some(light) = worst else {
        return vec![1.0; data.n_excitation()];
    };
    let pc = crate::colour::PatchColorimeter::cached(light, &data.excitation_nm, &data.emission_nm);
    let reach = pc.weights().0;
    let peak = reach.iter().cloned().fold(0.0, f64::max);
    if peak > 0.0 {
        reach.iter().map(|w| w / peak).collect()
    } else {
        vec![1.0; data.n_excitation()]
    }
}

/// Where a candidate's solver starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Start {
    /// The one-component parent's optimum, plus (K > 1) a small extra component from
    /// the parent's weighted residual.
    Parent,
    /// A fresh split of the matrix by a masked non-negative factorisation.
    Split,
    /// The tabulated fit's fluorophore plus (K > 1) an extra component from the cells
    /// that fit leaves empty: a weak emitter the parent, pulled by the colour term, would
    /// otherwise hide.
    Base,
    /// The optimum of the best smaller model the candidate contains, extra parts small.
    Nested,
    /// The other yield form's optimum of the same structure.
    Twin,
}

/// The starting parameters: bands fitted to the tabulated fit's spectra (K = 1) or to
/// the components of a masked non-negative factorisation (K > 1).
pub(super) fn start(
    problem: &Problem<'_>,
    ctx: &CandidateContext<'_>,
    one_component: Option<&(ModelSpec, Vec<f64>)>,
    kind: Start,
) -> Result<Vec<f64>> {
    let base = ctx.base;
    let data = problem.data;
    let layout = problem.layout;
    let spec = layout.spec;
    let mut theta = vec![0.0; layout.len];
    // Components as (κ, absorption on the excitation grid, emission density on the
    // emission grid).
    let components: Vec<(f64, Vec<f64>, Vec<f64>)> = if spec.components == 1 {
        let f = &base.fluorophores[0];
        vec![(
            start_kappa(f, spec.yield_form),
            f.absorption
                .resample_zero_outside(&data.excitation_nm)
                .value,
            f.emission.resample_zero_outside(&data.emission_nm).value,
        )]
    } else {
        let parent = if kind == Start::Base {
            None
        } else {
            one_component
        };
        split_components(problem, ctx, parent, kind)
    };
    // The parent's own parameters, when it has this model's bands: the start then costs
    // what the parent's optimum costs plus a small extra component.
    let copied = match one_component {
        Some((parent_spec, parent_theta))
            if spec.components > 1
                && kind == Start::Parent
                && parent_spec.absorption_bands == spec.absorption_bands
                && parent_spec.emission_bands == spec.emission_bands
                && parent_spec.reflectance == spec.reflectance =>
        {
            let parent_layout = crate::fit::parametric::Layout::new(*parent_spec);
            theta[0] = parent_theta[0];
            theta[layout.absorption(0)].copy_from_slice(&parent_theta[parent_layout.absorption(0)]);
            theta[layout.emission(0)].copy_from_slice(&parent_theta[parent_layout.emission(0)]);
            theta[layout.reflectance()].copy_from_slice(&parent_theta[parent_layout.reflectance()]);
            true
        }
        _ => false,
    };
    let parent_kappa = theta[0].sin().powi(2);
    for (k, (kappa, absorption, emission)) in components.iter().enumerate() {
        if copied && k == 0 {
            continue;
        }
        // An added component starts small and inside Σκ·a ≤ 1: the start then costs
        // about what the parent's optimum costs, and the solver grows what helps.
        let kappa = if copied {
            // Room left where this component absorbs: Σκ·a ≤ 1 with the parent's κ·a.
            let parent_absorbed: Vec<f64> = match one_component {
                Some((parent_spec, parent_theta)) => {
                    let p = Problem::new(data, *parent_spec, &[], &[], 0.0);
                    let gm = p.grid_model(parent_theta);
                    gm.absorption[0].iter().map(|a| gm.kappa[0] * a).collect()
                }
                None => vec![parent_kappa; absorption.len()],
            };
            let room = room(absorption, &parent_absorbed);
            kappa
                .min(EXTRA_COMPONENT_SHARE * parent_kappa)
                .min(0.9 * room)
        } else {
            *kappa
        };
        set_component(problem, ctx, &mut theta, k, kappa, absorption, emission)?;
    }
    if let ReflectanceForm::Polynomial(degree) = spec.reflectance
        && !copied
    {
        let nm = &base.reflectance.wavelength_nm;
        let weights = diagonal_weights(base);
        let coefficients =
            match fit_sigmoid_polynomial(nm, &base.reflectance.value, Some(&weights), degree) {
                Ok(fit) => fit.form.coefficients,
                Err(_) => {
                    let mean = base.reflectance.value.iter().sum::<f64>()
                        / base.reflectance.value.len().max(1) as f64;
                    let mut c = vec![0.0; degree + 1];
                    c[0] = logit(mean);
                    c
                }
            };
        theta[layout.reflectance()].copy_from_slice(&coefficients);
    }
    problem.clamp_to_box(&mut theta);
    Ok(theta)
}

/// The κ of `spec`'s form that gives the fluorophore `f` its fluorescence at its
/// absorption peak: the smallest feasible c of the energy form (k·max(1, λ̄e/λmin)), k of
/// the photon form (its energy yield there times λ̄e/λpeak).
pub(super) fn start_kappa(f: &crate::Fluorophore, form: YieldForm) -> f64 {
    let a = &f.absorption;
    let peak_nm = (0..a.len())
        .max_by(|&x, &y| a.value[x].total_cmp(&a.value[y]))
        .map(|i| a.wavelength_nm[i])
        .unwrap_or(500.0);
    let mean = f.emission_mean_nm();
    if !mean.is_finite() || f.yield_form == form {
        return f.concentration;
    }
    let k_at_peak = f.concentration * f.energy_yield_with_mean(peak_nm, mean);
    match form {
        YieldForm::Photon => k_at_peak * mean / peak_nm,
        YieldForm::Energy => {
            let shortest = f.shortest_absorbed_nm().unwrap_or(peak_nm);
            k_at_peak * (mean / shortest).max(1.0)
        }
    }
}

/// Which factors a K > 1 start splits its components from: its kind, its one-component
/// parent (spec and parameters' bits) and K.
type FactorKey = (Start, Option<(ModelSpec, Vec<u64>)>, usize);

/// Which bands a start fits to a spectrum: its grid, its values (bits), the band axis
/// and the number of bands.
type BandKey = (Vec<u64>, Vec<u64>, BandDomain, usize);

/// Which spectrum bands are grown on: [`BandKey`] without the number of bands.
type GrowthKey = (Vec<u64>, Vec<u64>, BandDomain);

/// What the starts of a search share (over both its band axes), each computed once: the factors K > 1 starts
/// split their components from, and the bands fitted to a start's spectra. They depend
/// on the search's cells, noise and grid fit and on their keys alone, and the candidates
/// of one search ask for the same ones: CIBA12's noise-aware search factorised the same
/// split for each of its five two-component structures (13 % of its time in `masked_nmf`
/// and `fit_factor`), and fitted the same spectra with the same bands again wherever two
/// structures share a band count (its start bands took 9 %).
#[derive(Default)]
pub(super) struct StartCache {
    factors: Memo<FactorKey, Factors>,
    bands: Memo<BandKey, Result<Vec<f64>>>,
    /// Each spectrum's bands grown so far: the ladder asks for one spectrum's fit with 1,
    /// 2 and 3 bands, and each count grew every band before it again (band fits were
    /// 11 % of HERPICER's noise-aware search).
    growths: Memo<GrowthKey, Arc<Mutex<BandGrowth>>>,
}

/// One memoised value: computed once, by whichever start asks first.
type Memo<K, V> = Mutex<Vec<(K, Arc<OnceLock<V>>)>>;

/// The value memoised under `key` in `memo`, computed by `compute` the first time. Its
/// cell is taken under the lock and filled outside it: a start asking for a key another
/// is computing waits for that value (the two axes' searches, beside each other, ask for
/// the same fresh split of the grid fit at about the same time) instead of computing it
/// again, and starts asking for different keys do not wait for each other.
fn memoised<K: PartialEq, V: Clone>(memo: &Memo<K, V>, key: K, compute: impl FnOnce() -> V) -> V {
    let cell = match memo.lock() {
        Ok(mut kept) => match kept.iter().find(|(k, _)| *k == key) {
            Some((_, cell)) => Arc::clone(cell),
            None => {
                let cell = Arc::new(OnceLock::new());
                kept.push((key, Arc::clone(&cell)));
                cell
            }
        },
        // A poisoned lock (a start panicked): compute without memoising.
        Err(_) => return compute(),
    };
    cell.get_or_init(compute).clone()
}

impl StartCache {
    /// The factors for `key`, computed by `compute` the first time.
    fn factors(&self, key: FactorKey, compute: impl FnOnce() -> Factors) -> Factors {
        memoised(&self.factors, key, compute)
    }

    /// The raw parameters of `n_bands` bands on `domain` fitted to `values` on `nm`
    /// ([`fit_bands`]).
    fn bands(
        &self,
        nm: &[f64],
        values: &[f64],
        domain: BandDomain,
        n_bands: usize,
    ) -> Result<Vec<f64>> {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        let (nm_bits, value_bits) = (bits(nm), bits(values));
        memoised(
            &self.bands,
            (nm_bits.clone(), value_bits.clone(), domain, n_bands),
            || {
                let growth = memoised(&self.growths, (nm_bits, value_bits, domain), || {
                    Arc::new(Mutex::new(BandGrowth::new(nm, values, domain)))
                });
                // A poisoned lock (a start panicked): fit without the growth kept.
                let fit = match growth.lock() {
                    Ok(mut growth) => growth.fit(n_bands),
                    Err(_) => fit_bands(nm, values, domain, n_bands),
                };
                fit.map(|fit| fit.bands.params())
            },
        )
    }
}

/// K components from a masked non-negative factorisation of the off-diagonal cells,
/// started from the one-component fit and the residual it leaves.
pub(super) fn split_components(
    problem: &Problem<'_>,
    ctx: &CandidateContext<'_>,
    one_component: Option<&(ModelSpec, Vec<f64>)>,
    kind: Start,
) -> Vec<(f64, Vec<f64>, Vec<f64>)> {
    let data = problem.data;
    let column_factor: Vec<f64> = data
        .emission_bin_widths
        .iter()
        .zip(&data.emission_weight)
        .map(|(w, ew)| w / ew)
        .collect();
    let key = (
        kind,
        one_component.map(|(spec, theta)| (*spec, theta.iter().map(|t| t.to_bits()).collect())),
        problem.layout.spec.components,
    );
    let factors = ctx.start_cache.factors(key, || {
        split_factors(problem, ctx, one_component, kind, &column_factor)
    });
    factors
        .rows
        .iter()
        .zip(&factors.columns)
        .map(|(row, column)| {
            let peak = row.iter().cloned().fold(0.0, f64::max).max(1e-300);
            let absorption: Vec<f64> = row.iter().map(|v| v / peak).collect();
            let emission: Vec<f64> = column
                .iter()
                .zip(&column_factor)
                .map(|(v, u)| v / u)
                .collect();
            let normaliser: f64 = emission
                .iter()
                .zip(&data.emission_bin_widths)
                .map(|(e, w)| e * w)
                .sum::<f64>()
                .max(1e-300);
            let mean: f64 = emission
                .iter()
                .zip(&data.emission_bin_widths)
                .zip(&data.emission_nm)
                .map(|((e, w), l)| e * w * l)
                .sum::<f64>()
                / normaliser;
            let shortest = absorption
                .iter()
                .position(|&a| a >= crate::fit::parametric::ABSORPTION_FLOOR)
                .map(|i| data.excitation_nm[i.saturating_sub(1)])
                .unwrap_or(data.excitation_nm[0]);
            // F = peak·a·e·u = s·a·x·e·u with s = κ/(γ·S): γ = max(1, λ̄e/λmin) and x = 1
            // in the energy form; γ = 1 and x = λi/λ̄e (taken at the peak) in the photon
            // form.
            let peak_nm = data.excitation_nm[absorption
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(b.1))
                .map(|(i, _)| i)
                .unwrap_or(0)];
            let photon_factor = match problem.layout.spec.yield_form {
                YieldForm::Energy => (mean / shortest).max(1.0),
                YieldForm::Photon => mean / peak_nm,
            };
            let kappa = peak * photon_factor * normaliser;
            (
                kappa,
                absorption,
                emission.iter().map(|e| e / normaliser).collect(),
            )
        })
        .collect()
}

/// The factors of [`split_components`] before they become bands: the one-component
/// fit's (the parent's, else the grid fit's), each further component the weighted rank-1
/// part of what the others leave, refined by a masked factorisation for [`Start::Split`].
fn split_factors(
    problem: &Problem<'_>,
    ctx: &CandidateContext<'_>,
    one_component: Option<&(ModelSpec, Vec<f64>)>,
    kind: Start,
    column_factor: &[f64],
) -> Factors {
    let (base, sigma, focus) = (ctx.base, ctx.sigma, ctx.focus);
    let data = problem.data;
    let k_count = problem.layout.spec.components;
    // The first components: those of the fitted model (parametric if fitted, else the
    // tabulated fit's one).
    let (rows, columns): (Vec<Vec<f64>>, Vec<Vec<f64>>) = match one_component {
        Some((spec, theta)) => {
            let p = Problem::new(data, *spec, &[], &[], 0.0);
            let gm = p.grid_model(theta);
            (0..gm.kappa.len())
                .map(|k| {
                    let row: Vec<f64> = gm.absorption[k]
                        .iter()
                        .zip(&gm.excitation_factor[k])
                        .map(|(a, x)| a * x * gm.scale[k])
                        .collect();
                    let column: Vec<f64> = gm.emission[k]
                        .iter()
                        .zip(column_factor)
                        .map(|(e, u)| e * u)
                        .collect();
                    (row, column)
                })
                .unzip()
        }
        None => {
            let f = &base.fluorophores[0];
            // The matrix's row factor c·Q(λi)·a(λi), in either yield form.
            let mean = f.emission_mean_nm();
            let row = data
                .excitation_nm
                .iter()
                .map(|&l| f.reradiated_with_mean(l, mean))
                .collect();
            let column = f
                .emission
                .resample_zero_outside(&data.emission_nm)
                .value
                .iter()
                .zip(column_factor)
                .map(|(e, u)| e * u)
                .collect();
            (vec![row], vec![column])
        }
    };
    let (mut rows, mut columns) = (rows, columns);
    // Each further component starts as the weighted rank-1 part of what the others leave,
    // weighted by 1/(model + 3σ)²: a weak second emitter (a brightener's blue under UV)
    // hides in cells the first leaves near zero, not in the first's relative misfit.
    for _ in rows.len()..k_count {
        let mut residual = data.clone();
        let mut weights = Vec::with_capacity(residual.off_diagonal.len());
        for c in residual.off_diagonal.iter_mut() {
            let explained: f64 = rows
                .iter()
                .zip(&columns)
                .map(|(r, col)| r[c.row] * col[c.column])
                .sum();
            c.value -= explained;
            weights.push(if kind == Start::Base {
                // Only the cells the others leave empty.
                if explained < 3.0 * sigma {
                    focus[c.row]
                } else {
                    0.0
                }
            } else {
                (explained.abs() + 3.0 * sigma).powi(-2)
            });
        }
        let (row, column) = weighted_rank_one(&residual, &weights, 50);
        // Its size: the plain least-squares projection of the residual on its shape (the
        // weighted fit would inflate it where the model is small).
        let (mut num, mut den) = (0.0, 0.0);
        for c in &residual.off_diagonal {
            let shape = row[c.row] * column[c.column];
            num += c.value * shape;
            den += shape * shape;
        }
        let size = if den > 0.0 {
            (num / den).max(1e-3)
        } else {
            1e-3
        };
        let floor = sigma * 1e-3;
        rows.push(row.iter().map(|v| (v * size).max(floor)).collect());
        columns.push(column.iter().map(|v| v.max(floor)).collect());
    }
    if kind == Start::Split {
        masked_nmf(data, Factors { rows, columns }, SPLIT_SWEEPS)
    } else {
        Factors { rows, columns }
    }
}
