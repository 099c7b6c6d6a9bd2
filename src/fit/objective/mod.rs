//! The least-squares objective on the grid spectra (κ, a, v) and its derivatives.
//!
//! Off the diagonal the model is F_ij = s·a_i·x_i·v_j. In the energy form (constant
//! energy yield Q) x_i = 1 and s = κ/(γ·S): S normalises the emission (∫e = 1),
//! γ = max(1, λ̄e/λmin) is the photon factor and κ = k·γ. In the photon form (constant
//! photon yield Φ, energy yield Φ·λi/λ̄e; model.md §3) x_i = λ_i and s = κ/M with
//! M = Σ v_j·w_j·λ_j = λ̄e·S, and κ = c·Φ. Either way κ is the smallest concentration the
//! constraints allow, and κ ≤ 1 is exactly "some valid c exists" when max a = 1.
//!
//! On the diagonal the reflectance d_j is eliminated in closed form: it is the projection
//! of M_jj − F_jj onto its feasible interval [0, 1 − κ·a_j·m_j], with m_j = 1 in the
//! energy form and max(1, λ_j/λ̄e) in the photon form (r ≤ 1 at the smallest c, and the
//! energy law where the energy yield Φ·λ/λ̄e exceeds Φ). So every point the solver visits
//! is a valid material and the diagonal residual is what that projection cannot absorb.
//!
//! An optional colour term (½·w·Σ ΔE76² of the flat patch under the scene's lights,
//! CIELAB linearised at the measured colour, model.md §7) is a linear function of the
//! cell residuals, so it differentiates like the matrix term.

use nalgebra::DMatrix;

use crate::material::YieldForm;

pub use super::colour_term::{COLOUR_SCALE, ColourTerm};
use super::data::{Cell, FitData};
use super::representation::GridSpectra;
use crate::numeric::{dot, zeros};

/// Weight of the term that fixes the free scale of the emission samples (S = 1). The
/// model does not depend on that scale, so the term changes no fitted material.
pub(crate) const SCALE_GAUGE_WEIGHT: f64 = 1e-4;

/// Quantities derived from the grid spectra that the model needs.
#[derive(Debug, Clone, Copy)]
pub struct Derived {
    /// S = Σ v_j·w_j: the emission normaliser.
    pub normaliser: f64,
    /// M = Σ v_j·w_j·λ_j = λ̄e·S.
    pub moment: f64,
    /// λ̄e, the mean emission wavelength (nm).
    pub emission_mean_nm: f64,
    /// λmin, the infimum of absorbed wavelengths (nm).
    pub shortest_absorbed_nm: f64,
    /// γ = max(1, λ̄e/λmin) in the energy form; 1 in the photon form (Φ ≤ 1 is the
    /// photon law there).
    pub photon_factor: f64,
    /// Whether γ > 1 (the photon law is stricter than Q ≤ 1; energy form only).
    pub photon_limited: bool,
    /// κ/s: γ·S in the energy form, M in the photon form.
    pub kappa_per_scale: f64,
    /// s = κ/(κ/s), the scale of the off-diagonal product.
    pub scale: f64,
}

/// Where a fitted diagonal reflectance sits in its feasible interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagonalRegime {
    /// Inside: the diagonal is matched exactly.
    Free,
    /// Clamped at d = 0: the fluorescent term alone exceeds the measured diagonal.
    AtZero,
    /// Clamped at d = 1 − κ·a·m: conservation caps the reflectance.
    AtCap,
}

/// One diagonal cell as the fit sees it.
#[derive(Debug, Clone, Copy)]
struct DiagonalFit {
    /// The fitted reflectance d_j: M_jj − F_jj projected onto [0, cap].
    reflectance: f64,
    /// Measured − model (0 inside the interval).
    residual: f64,
    /// Where d_j sits.
    regime: DiagonalRegime,
}

/// The objective for one measurement.
#[derive(Debug, Clone)]
pub struct Objective<'a> {
    /// The cells.
    pub data: &'a FitData,
    /// The yield form of the fluorophore.
    pub form: YieldForm,
    /// x_i: 1 (energy form) or λ_i (photon form).
    row_factor: Vec<f64>,
    /// The colour term, if any: set only by [`Objective::with_colour`], which also
    /// stores its sums over the measured values (`colour_measured`).
    colour: Option<ColourTerm>,
    /// The off-diagonal cells, dense (row-major, excitation × emission): 1 where the
    /// matrix term fits a cell, 0 elsewhere. Dense rows vectorise; cell lists did not
    /// (perf: the cell loops were 70 % of a default fit).
    fitted_mask: Vec<f64>,
    /// 1 where the colour term sees an off-diagonal cell (fitted and guard cells).
    seen_mask: Vec<f64>,
    /// Measured values on those cells, 0 elsewhere.
    dense_value: Vec<f64>,
    /// The cells (row, column) the colour term does not see (`seen_mask` 0): the
    /// diagonal and unmeasured cells.
    unseen: Vec<(usize, usize)>,
    /// The colour term's column sums of the measured values, Σ_i L_li·M_ij over the seen
    /// cells (light-major), set with the colour term.
    colour_measured: Vec<f64>,
    /// ∫L·h_i of each light for the row of each `unseen` cell (light-major: light l's are
    /// `unseen.len()` in a row), set with the colour term: the unseen cells' loops then
    /// run a light at a time over contiguous weights.
    unseen_lights: Vec<f64>,
}

impl<'a> Objective<'a> {
    /// The matrix-only objective of `data` in the yield form `form`.
    pub fn new(data: &'a FitData, form: YieldForm) -> Self {
        let row_factor = match form {
            YieldForm::Energy => vec![1.0; data.n_excitation()],
            YieldForm::Photon => data.excitation_nm.clone(),
        };
        let n_em = data.n_emission();
        let cells = data.n_excitation() * n_em;
        let (mut fitted_mask, mut seen_mask, mut dense_value) =
            (vec![0.0; cells], vec![0.0; cells], vec![0.0; cells]);
        for c in &data.off_diagonal {
            fitted_mask[c.row * n_em + c.column] = 1.0;
        }
        for c in data.off_diagonal.iter().chain(&data.guard) {
            seen_mask[c.row * n_em + c.column] = 1.0;
            dense_value[c.row * n_em + c.column] = c.value;
        }
        let unseen = seen_mask
            .iter()
            .enumerate()
            .filter(|(_, m)| **m == 0.0)
            .map(|(k, _)| (k / n_em, k % n_em))
            .collect();
        Objective {
            data,
            form,
            row_factor,
            colour: None,
            fitted_mask,
            seen_mask,
            dense_value,
            unseen,
            colour_measured: Vec::new(),
            unseen_lights: Vec::new(),
        }
    }

    /// Residuals M − F of the off-diagonal cells (fitted and guard), dense, 0 elsewhere.
    fn dense_residuals(&self, sp: &GridSpectra, d: &Derived) -> Vec<f64> {
        let mut residual = Vec::with_capacity(self.dense_value.len());
        for i in 0..self.data.n_excitation() {
            self.push_residual_row(sp, d, i, &mut residual);
        }
        residual
    }

    /// Row `i` of [`Objective::dense_residuals`], pushed onto `out`. Zipped slices
    /// extending a vector: the nested zips over chunk iterators did not vectorise (perf:
    /// 14 instructions a cell).
    #[inline(always)]
    fn push_residual_row(&self, sp: &GridSpectra, d: &Derived, i: usize, out: &mut Vec<f64>) {
        let n_em = sp.emission.len();
        let u = d.scale * sp.absorption[i] * self.row_factor[i];
        let values = &self.dense_value[i * n_em..(i + 1) * n_em];
        let mask = &self.seen_mask[i * n_em..(i + 1) * n_em];
        out.extend(
            values
                .iter()
                .zip(mask)
                .zip(&sp.emission)
                .map(|((value, m), v)| m * (value - u * v)),
        );
    }

    /// The colour term's column sums Σ_i L_li·r_ij (light-major) of dense residuals.
    fn column_sums(&self, colour: &ColourTerm, residual: &[f64]) -> Vec<f64> {
        let n_em = self.data.n_emission();
        let mut column_sum = vec![0.0; colour.n_lights * n_em];
        for (i, row) in residual.chunks_exact(n_em).enumerate() {
            for (l, &w) in colour.lights_of_row(i).iter().enumerate() {
                let sums = &mut column_sum[l * n_em..(l + 1) * n_em];
                for j in 0..n_em {
                    sums[j] += w * row[j];
                }
            }
        }
        column_sum
    }

    /// This objective with a colour term.
    pub fn with_colour(mut self, colour: Option<ColourTerm>) -> Self {
        self.colour_measured = match &colour {
            Some(colour) => self.column_sums(colour, &self.dense_value),
            None => Vec::new(),
        };
        self.unseen_lights = match &colour {
            Some(colour) => (0..colour.n_lights)
                .flat_map(|l| self.unseen.iter().map(move |&(i, _)| (i, l)))
                .map(|(i, l)| colour.lights_of_row(i)[l])
                .collect(),
            None => Vec::new(),
        };
        self.colour = colour;
        self
    }

    /// x_i, the excitation factor of row i (1, or λ_i in the photon form).
    pub fn row_factor(&self, row: usize) -> f64 {
        self.row_factor[row]
    }

    /// The fitted off-diagonal value of cell (i, j).
    pub fn fitted(&self, sp: &GridSpectra, d: &Derived, row: usize, column: usize) -> f64 {
        d.scale * sp.absorption[row] * self.row_factor[row] * sp.emission[column]
    }

    /// Derived quantities for the spectra `sp`.
    pub fn derived(&self, sp: &GridSpectra) -> Derived {
        let data = self.data;
        let (normaliser, moment) = data.emission_sum_moment(&sp.emission);
        let emission_mean_nm = if normaliser > 0.0 {
            moment / normaliser
        } else {
            f64::NAN
        };
        let shortest_absorbed_nm = shortest_positive(&sp.absorption, &data.excitation_nm);
        let (photon_factor, photon_limited, kappa_per_scale) = match self.form {
            YieldForm::Energy => {
                let ratio = emission_mean_nm / shortest_absorbed_nm;
                let limited = ratio.is_finite() && ratio > 1.0;
                let gamma = if limited { ratio } else { 1.0 };
                (gamma, limited, gamma * normaliser)
            }
            YieldForm::Photon => (1.0, false, moment),
        };
        let scale = if normaliser > 0.0 && kappa_per_scale > 0.0 {
            sp.kappa / kappa_per_scale
        } else {
            0.0
        };
        Derived {
            normaliser,
            moment,
            emission_mean_nm,
            shortest_absorbed_nm,
            photon_factor,
            photon_limited,
            kappa_per_scale,
            scale,
        }
    }

    /// m_i: the factor of κ·a_i in the diagonal's cap (1, or max(1, λ_i/λ̄e) in the
    /// photon form).
    fn cap_factor(&self, d: &Derived, row: usize) -> f64 {
        match self.form {
            YieldForm::Energy => 1.0,
            YieldForm::Photon => {
                let ratio = self.data.excitation_nm[row] / d.emission_mean_nm;
                if ratio.is_finite() {
                    ratio.max(1.0)
                } else {
                    1.0
                }
            }
        }
    }

    /// The diagonal's cap 1 − κ·a_i·m_i at row `row`.
    pub fn cap(&self, sp: &GridSpectra, d: &Derived, row: usize) -> f64 {
        1.0 - sp.kappa * sp.absorption[row] * self.cap_factor(d, row)
    }

    /// Every diagonal cell of `data.diagonal` projected onto its feasible interval.
    /// A loop, inlined: as a `collect` it stayed an out-of-line generic, outside the
    /// objective's AVX2 build (callgrind: 59 instructions a cell).
    #[inline(always)]
    fn diagonal_fits(&self, sp: &GridSpectra, d: &Derived) -> Vec<DiagonalFit> {
        let mut fits = Vec::with_capacity(self.data.diagonal.len());
        for c in &self.data.diagonal {
            let raw = c.value - self.fitted(sp, d, c.row, c.column);
            let cap = self.cap(sp, d, c.row);
            let (reflectance, regime) = if raw < 0.0 {
                (0.0, DiagonalRegime::AtZero)
            } else if raw > cap {
                (cap, DiagonalRegime::AtCap)
            } else {
                (raw, DiagonalRegime::Free)
            };
            fits.push(DiagonalFit {
                reflectance,
                residual: raw - reflectance,
                regime,
            });
        }
        fits
    }

    /// The fitted diagonal reflectance d_j (per diagonal cell of `data.diagonal`) and where
    /// it sits in its feasible interval.
    pub fn diagonal(&self, sp: &GridSpectra, d: &Derived) -> Vec<(f64, DiagonalRegime)> {
        self.diagonal_fits(sp, d)
            .into_iter()
            .map(|f| (f.reflectance, f.regime))
            .collect()
    }

    /// The colour term's ΔLab (measured − model) per light and channel for the spectra
    /// `sp`: the column sums of the dense residuals (the colour sees every measured
    /// off-diagonal cell), then the diagonal's residuals.
    fn colour_patch(
        &self,
        colour: &ColourTerm,
        sp: &GridSpectra,
        d: &Derived,
        diagonal: &[DiagonalFit],
    ) -> Vec<f64> {
        let column_sum = self.column_sums(colour, &self.dense_residuals(sp, d));
        self.colour_patch_from_sums(colour, &column_sum, diagonal)
    }

    /// [`Objective::colour_patch`] from the residuals' column sums Σ_i L_li·r_ij.
    #[inline(always)]
    fn colour_patch_from_sums(
        &self,
        colour: &ColourTerm,
        column_sum: &[f64],
        diagonal: &[DiagonalFit],
    ) -> Vec<f64> {
        let diagonal = self
            .data
            .diagonal
            .iter()
            .zip(diagonal)
            .map(|(c, f)| (c.column, f.residual));
        colour.patch(column_sum, diagonal, self.data.n_emission())
    }

    /// ½‖r‖² (plus the colour term) and its gradient with respect to (κ, a, v).
    pub fn cost_gradient(&self, sp: &GridSpectra) -> (f64, f64, Vec<f64>, Vec<f64>) {
        // The cell loops are most of a grid fit; compiled for AVX2 as well and chosen at
        // run time. Without FMA contraction (not enabled) and with the loops' order of
        // additions fixed, both builds give the same bits.
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { self.cost_gradient_avx2(sp) };
        }
        self.cost_gradient_body(sp)
    }

    /// [`Objective::cost_gradient`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn cost_gradient_avx2(&self, sp: &GridSpectra) -> (f64, f64, Vec<f64>, Vec<f64>) {
        self.cost_gradient_body(sp)
    }

    /// The body of [`Objective::cost_gradient`], inlined into each build.
    #[inline(always)]
    fn cost_gradient_body(&self, sp: &GridSpectra) -> (f64, f64, Vec<f64>, Vec<f64>) {
        let data = self.data;
        let n_em = data.n_emission();
        let d = self.derived(sp);
        let (a, v, s, x) = (&sp.absorption, &sp.emission, d.scale, &self.row_factor);
        let mut cost = 0.0;
        let mut g_scale = 0.0;
        let mut g_kappa = 0.0;
        let mut g_a = zeros(a.len());
        let mut g_v = zeros(v.len());
        let diagonal = self.diagonal_fits(sp, &d);
        cost += 0.5
            * diagonal
                .iter()
                .map(|f| f.residual * f.residual)
                .sum::<f64>();
        let n_ex = data.n_excitation();
        // The model's row factors u_i = s·a_i·x_i: F_ij = u_i·v_j off the diagonal.
        // Loops filling vectors, not `collect`s, here and below: a `collect` stays an
        // out-of-line generic compiled without AVX2 (callgrind: a fifth of an evaluation).
        let mut u = zeros(n_ex);
        for ((ui, ai), xi) in u.iter_mut().zip(a).zip(x) {
            *ui = s * ai * xi;
        }
        let v = &v[..n_em];
        // The colour term is linear in the residuals r_ij = M_ij − u_i·v_j of the cells it
        // sees (fitted and guard cells), so its sums over them are the sums over every
        // cell less those over the few it does not see (the diagonal, unmeasured cells):
        // O(lights·(rows + columns)) instead of O(lights·cells) (perf: the per-cell light
        // loops were two thirds of an evaluation).
        let (h, colour_along) = match &self.colour {
            Some(colour) => {
                let n_l = colour.n_lights;
                let constant = &self.colour_measured;
                // Σ_i L_li·u_i over the seen cells of each column, then the column sums
                // Σ_i L_li·r_ij = Σ_i L_li·M_ij − v_j·Σ_i L_li·u_i.
                let mut lit = zeros(n_l);
                for (i, ui) in u.iter().enumerate() {
                    for (t, w) in lit.iter_mut().zip(colour.lights_of_row(i)) {
                        *t += w * ui;
                    }
                }
                let mut seen_lit = zeros(n_l * n_em);
                for (seen, t) in seen_lit.chunks_exact_mut(n_em).zip(&lit) {
                    seen.fill(*t);
                }
                // A light at a time: each sum still takes the unseen cells in their order.
                // (chunks of at least 1: a matrix may have no unseen cell)
                let n_unseen = self.unseen.len().max(1);
                for (seen, weights) in seen_lit
                    .chunks_exact_mut(n_em)
                    .zip(self.unseen_lights.chunks_exact(n_unseen))
                {
                    for (&(i, j), w) in self.unseen.iter().zip(weights) {
                        seen[j] -= w * u[i];
                    }
                }
                let mut column_sum = zeros(n_l * n_em);
                for ((sums, c), t) in column_sum
                    .chunks_exact_mut(n_em)
                    .zip(constant.chunks_exact(n_em))
                    .zip(seen_lit.chunks_exact(n_em))
                {
                    for ((sum, c), (vj, t)) in sums.iter_mut().zip(c).zip(v.iter().zip(t)) {
                        *sum = c - vj * t;
                    }
                }
                let patch = self.colour_patch_from_sums(colour, &column_sum, &diagonal);
                let (colour_cost, pull_patch) = colour.robust(&patch);
                cost += colour_cost;
                let (q, h) = colour.pulls(&pull_patch, n_em);
                // The pull Σ_l L_li·q_lj on each seen cell: along v per row, and into the
                // emission gradient per column (weighted by the row's u_i).
                let mut qv = zeros(n_l);
                for (qv_l, q_l) in qv.iter_mut().zip(q.chunks_exact(n_em)) {
                    *qv_l = dot(q_l, v);
                }
                let mut along = zeros(n_ex);
                for (i, along_i) in along.iter_mut().enumerate() {
                    *along_i = dot(colour.lights_of_row(i), &qv);
                }
                // Each unseen cell's pull Σ_l L_li·q_lj, summed a light at a time (from −0.0,
                // as `sum` does) over contiguous weights.
                let mut pulls = vec![-0.0; n_unseen];
                for (q_l, weights) in q
                    .chunks_exact(n_em)
                    .zip(self.unseen_lights.chunks_exact(n_unseen))
                {
                    for ((pull, &(_, j)), w) in pulls.iter_mut().zip(&self.unseen).zip(weights) {
                        *pull += w * q_l[j];
                    }
                }
                for (&(i, j), pull) in self.unseen.iter().zip(&pulls) {
                    along[i] -= pull * v[j];
                }
                // Σ_i u_i·L_li over each column's seen cells is `seen_lit` again.
                for (l, weights) in seen_lit.chunks_exact(n_em).enumerate() {
                    let ql = &q[l * n_em..(l + 1) * n_em];
                    for ((g, qj), t) in g_v.iter_mut().zip(ql).zip(weights) {
                        *g -= qj * t;
                    }
                }
                (h, along)
            }
            None => (zeros(n_em), zeros(n_ex)),
        };
        // Off-diagonal fitted cells, row by row: ∂cost/∂F = −r (the colour's pull is
        // added above).
        let mut matrix_cost = 0.0;
        let g_v_row = &mut g_v[..n_em];
        let rows = self
            .dense_value
            .chunks_exact(n_em)
            .zip(self.fitted_mask.chunks_exact(n_em));
        let per_row = u.iter().zip(a).zip(x).zip(&colour_along).zip(&mut g_a);
        for ((values, fitted), ((((ui, ai), xi), colour_along), g_ai)) in rows.zip(per_row) {
            let (row_cost, row_along) = matrix_row(values, fitted, v, *ui, g_v_row);
            matrix_cost += row_cost;
            let along_v = row_along + colour_along;
            g_scale -= along_v * ai * xi;
            *g_ai -= along_v * s * xi;
        }
        cost += 0.5 * matrix_cost;
        for (c, fit) in data.diagonal.iter().zip(&diagonal) {
            let (r, regime) = (fit.residual, fit.regime);
            if regime == DiagonalRegime::Free {
                continue;
            }
            let effective = r + h[c.column];
            let (ai, xi, vj) = (a[c.row], x[c.row], v[c.column]);
            g_scale -= effective * ai * xi * vj;
            g_a[c.row] -= effective * s * xi * vj;
            g_v[c.column] -= effective * s * ai * xi;
            if regime == DiagonalRegime::AtCap {
                // r = raw − cap, cap = 1 − κ·a·m: ∂r/∂κ = a·m, ∂r/∂a = κ·m, ∂r/∂v via m.
                let m = self.cap_factor(&d, c.row);
                g_kappa += effective * ai * m;
                g_a[c.row] += effective * sp.kappa * m;
                if m > 1.0 {
                    let li = data.excitation_nm[c.row];
                    for (l, g) in g_v.iter_mut().enumerate() {
                        let dm = li * data.emission_weight[l] / d.moment
                            * (1.0 - data.emission_nm[l] / d.emission_mean_nm);
                        *g += effective * sp.kappa * ai * dm;
                    }
                }
            }
        }
        if d.normaliser > 0.0 && d.kappa_per_scale > 0.0 {
            g_kappa += g_scale / d.kappa_per_scale;
            for (j, g) in g_v.iter_mut().enumerate() {
                *g += g_scale * self.scale_derivative(&d, j);
            }
        }
        let gauge = d.normaliser - 1.0;
        cost += 0.5 * SCALE_GAUGE_WEIGHT * gauge * gauge;
        for (g, w) in g_v.iter_mut().zip(&data.emission_weight) {
            *g += SCALE_GAUGE_WEIGHT * gauge * w;
        }
        (cost, g_kappa, g_a, g_v)
    }

    /// ∂s/∂v_j.
    #[inline]
    fn scale_derivative(&self, d: &Derived, j: usize) -> f64 {
        let data = self.data;
        let w = data.emission_weight[j];
        match self.form {
            YieldForm::Energy => {
                let d_gamma = if d.photon_limited {
                    w * (data.emission_nm[j] - d.emission_mean_nm)
                        / (d.normaliser * d.shortest_absorbed_nm)
                } else {
                    0.0
                };
                -d.scale * (d_gamma / d.photon_factor + w / d.normaliser)
            }
            YieldForm::Photon => -d.scale * w * data.emission_nm[j] / d.moment,
        }
    }

    /// The residual vector r (off-diagonal cells, diagonal cells, the colour term's
    /// √w·ΔLab per light and channel, the scale gauge); the objective is ½‖r‖².
    pub fn residuals(&self, sp: &GridSpectra) -> Vec<f64> {
        let data = self.data;
        let d = self.derived(sp);
        let mut r = Vec::with_capacity(data.off_diagonal.len() + data.diagonal.len() + 13);
        for c in &data.off_diagonal {
            r.push(c.value - self.fitted(sp, &d, c.row, c.column));
        }
        let diagonal = self.diagonal_fits(sp, &d);
        r.extend(diagonal.iter().map(|f| f.residual));
        if let Some(colour) = &self.colour {
            let patch = self.colour_patch(colour, sp, &d, &diagonal);
            for (l, light) in patch.chunks_exact(3).enumerate() {
                let w = colour.light_weight(l).sqrt();
                let t = light.iter().map(|p| p * p).sum::<f64>().sqrt();
                let (phi, _) = colour.residual_factor(l, t);
                r.extend(light.iter().map(|p| w * phi * p));
            }
        }
        r.push(SCALE_GAUGE_WEIGHT.sqrt() * (d.normaliser - 1.0));
        r
    }

    /// ∂r/∂(κ, a, v) of one cell's residual in regime `regime` (AtZero stands for an
    /// off-diagonal cell: the full model term).
    fn cell_jacobian(
        &self,
        sp: &GridSpectra,
        d: &Derived,
        ds: &[f64],
        c: &Cell,
        regime: DiagonalRegime,
        out: &mut [f64],
    ) {
        let data = self.data;
        let n_ex = data.n_excitation();
        let kappa_scale = if d.kappa_per_scale > 0.0 {
            1.0 / d.kappa_per_scale
        } else {
            0.0
        };
        let xi = self.row_factor[c.row];
        let (ai, vj) = (sp.absorption[c.row], sp.emission[c.column]);
        out[0] = -ai * xi * vj * kappa_scale;
        out[1 + c.row] = -d.scale * xi * vj;
        for (l, dsl) in ds.iter().enumerate() {
            out[1 + n_ex + l] = -ai * xi * vj * dsl;
        }
        out[1 + n_ex + c.column] -= d.scale * ai * xi;
        if regime == DiagonalRegime::AtCap {
            let m = self.cap_factor(d, c.row);
            out[0] += ai * m;
            out[1 + c.row] += sp.kappa * m;
            if m > 1.0 {
                let li = data.excitation_nm[c.row];
                for l in 0..data.n_emission() {
                    let dm = li * data.emission_weight[l] / d.moment
                        * (1.0 - data.emission_nm[l] / d.emission_mean_nm);
                    out[1 + n_ex + l] += sp.kappa * ai * dm;
                }
            }
        }
    }

    /// ∂r/∂(κ, a, v): one row per residual of [`Objective::residuals`].
    pub fn jacobian(&self, sp: &GridSpectra) -> DMatrix<f64> {
        let data = self.data;
        let d = self.derived(sp);
        let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
        let n_colour = self.colour.as_ref().map_or(0, |c| 3 * c.n_lights);
        let rows = data.off_diagonal.len() + data.diagonal.len() + n_colour + 1;
        let n_params = 1 + n_ex + n_em;
        let mut j = DMatrix::zeros(rows, n_params);
        let ds: Vec<f64> = if d.normaliser > 0.0 {
            (0..n_em).map(|l| self.scale_derivative(&d, l)).collect()
        } else {
            vec![0.0; n_em]
        };
        let diagonal = self.diagonal_fits(sp, &d);
        let cells = data
            .off_diagonal
            .iter()
            .map(|c| (c, DiagonalRegime::AtZero))
            .chain(data.diagonal.iter().zip(diagonal.iter().map(|f| f.regime)));
        let mut row_buffer = vec![0.0; n_params];
        for (row, (c, regime)) in cells.enumerate() {
            if regime == DiagonalRegime::Free {
                continue;
            }
            row_buffer.iter_mut().for_each(|x| *x = 0.0);
            self.cell_jacobian(sp, &d, &ds, c, regime, &mut row_buffer);
            for (k, v) in row_buffer.iter().enumerate() {
                j[(row, k)] = *v;
            }
        }
        if let Some(colour) = &self.colour {
            // ∂ΔLab/∂θ (every measured cell through its coefficient), then through the
            // robust residual factor √w·φ(t).
            let mut d_patch: DMatrix<f64> = DMatrix::zeros(n_colour, n_params);
            let mut add = |coefficients: &mut dyn Iterator<Item = (usize, f64)>, row: &[f64]| {
                for (patch_row, coefficient) in coefficients {
                    for (k, v) in row.iter().enumerate() {
                        d_patch[(patch_row, k)] += coefficient * v;
                    }
                }
            };
            for c in data.off_diagonal.iter().chain(&data.guard) {
                row_buffer.iter_mut().for_each(|x| *x = 0.0);
                self.cell_jacobian(sp, &d, &ds, c, DiagonalRegime::AtZero, &mut row_buffer);
                let lights = colour.lights_of_row(c.row);
                add(
                    &mut (0..n_colour)
                        .map(|p| (p, lights[p / 3] * colour.emitted[p / 3][p % 3][c.column])),
                    &row_buffer,
                );
            }
            for (c, fit) in data.diagonal.iter().zip(&diagonal) {
                if fit.regime == DiagonalRegime::Free {
                    continue;
                }
                row_buffer.iter_mut().for_each(|x| *x = 0.0);
                self.cell_jacobian(sp, &d, &ds, c, fit.regime, &mut row_buffer);
                add(
                    &mut (0..n_colour).map(|p| (p, colour.reflected[p / 3][p % 3][c.column])),
                    &row_buffer,
                );
            }
            let first = data.off_diagonal.len() + data.diagonal.len();
            let patch = self.colour_patch(colour, sp, &d, &diagonal);
            for (l, p) in patch.chunks_exact(3).enumerate() {
                let root_weight = colour.light_weight(l).sqrt();
                let t = p.iter().map(|x| x * x).sum::<f64>().sqrt();
                let (phi, dphi) = colour.residual_factor(l, t);
                for k in 0..n_params {
                    let dp = [0, 1, 2].map(|ch| d_patch[(3 * l + ch, k)]);
                    let dt = if t > 0.0 {
                        (0..3).map(|ch| p[ch] * dp[ch]).sum::<f64>() / t
                    } else {
                        0.0
                    };
                    for ch in 0..3 {
                        j[(first + 3 * l + ch, k)] =
                            root_weight * (phi * dp[ch] + p[ch] * dphi * dt);
                    }
                }
            }
        }
        let gauge_row = rows - 1;
        for (l, w) in data.emission_weight.iter().enumerate() {
            j[(gauge_row, 1 + n_ex + l)] = SCALE_GAUGE_WEIGHT.sqrt() * w;
        }
        j
    }
}

/// One row of the matrix term: r_j = f_j·(M_j − u·v_j) on the fitted cells (mask
/// `fitted`), g_v −= u·r, and (Σ r², Σ r·v). One pass over four-lane chunks whose partial
/// sums are those of [`dot`] (same lanes, same order, the remainder summed apart), so the
/// result has the bits of the three passes it replaces, which took half again as many
/// instructions (callgrind: each pass paid its own setup and tails).
#[inline(always)]
fn matrix_row(values: &[f64], fitted: &[f64], v: &[f64], u: f64, g_v: &mut [f64]) -> (f64, f64) {
    let n = v.len();
    let split = n - n % 4;
    let (values, fitted, g_v) = (&values[..n], &fitted[..n], &mut g_v[..n]);
    let (mut squares, mut along) = ([0.0; 4], [0.0; 4]);
    let chunks = values[..split]
        .chunks_exact(4)
        .zip(fitted[..split].chunks_exact(4))
        .zip(v[..split].chunks_exact(4))
        .zip(g_v[..split].chunks_exact_mut(4));
    for (((m, f), vj), g) in chunks {
        // Whole lanes at a time, each step its own array: written per element, the loop
        // stayed scalar.
        let r: [f64; 4] = std::array::from_fn(|k| f[k] * (m[k] - u * vj[k]));
        let updated: [f64; 4] = std::array::from_fn(|k| g[k] - u * r[k]);
        g.copy_from_slice(&updated);
        squares = std::array::from_fn(|k| squares[k] + r[k] * r[k]);
        along = std::array::from_fn(|k| along[k] + r[k] * vj[k]);
    }
    // The remainder as `dot` sums it: a running sum from −0.0.
    let (mut tail_squares, mut tail_along) = (-0.0, -0.0);
    for j in split..n {
        let r = fitted[j] * (values[j] - u * v[j]);
        g_v[j] -= u * r;
        tail_squares += r * r;
        tail_along += r * v[j];
    }
    (
        squares.iter().sum::<f64>() + tail_squares,
        along.iter().sum::<f64>() + tail_along,
    )
}

/// The infimum of wavelengths where a > 0 for a piecewise-linear a: the sample before
/// the first positive one (absorption rises from it). NaN when a vanishes.
pub fn shortest_positive(absorption: &[f64], grid: &[f64]) -> f64 {
    match absorption.iter().position(|&x| x > 0.0) {
        Some(0) => grid[0],
        Some(i) => grid[i - 1],
        None => f64::NAN,
    }
}

#[cfg(test)]
mod tests;
