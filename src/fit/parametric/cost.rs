//! The parametric objective: the model on the grids for a parameter vector, the cost
//! (matrix cells, colour term, penalties) and its analytic gradient.

use super::scratch::Workspace;
use super::*;

impl<'a> Problem<'a> {
    /// Prepares the fit of `spec` to `data`. `lights` weight the rows by how much light
    /// reaches them and, with `reference` (the measured patch's XYZ under each light),
    /// give the colour term: ½·`colour_weight`·Σ ΔE76², linearised at the reference.
    pub fn new(
        data: &'a FitData,
        spec: ModelSpec,
        lights: &[Light],
        reference: &[Xyz],
        colour_weight: f64,
    ) -> Self {
        let domain = spec.domain;
        let widths = &data.emission_bin_widths;
        let column_factor: Vec<f64> = widths
            .iter()
            .zip(&data.emission_weight)
            .map(|(w, ew)| w / ew)
            .collect();
        let density_factor: Vec<f64> = column_factor.iter().map(|u| 1.0 / u).collect();
        let diagonal_nm: Vec<f64> = data
            .diagonal_positions
            .iter()
            .map(|&(_, j)| data.emission_nm[j])
            .collect();
        let reflectance_support = [
            diagonal_nm.first().copied().unwrap_or(380.0),
            diagonal_nm.last().copied().unwrap_or(780.0),
        ];
        let mut diagonal: Vec<DiagonalSample> = data
            .diagonal_positions
            .iter()
            .map(|&(row, column)| DiagonalSample {
                row,
                column,
                value: None,
                x: position(reflectance_support, data.emission_nm[column]),
            })
            .collect();
        for c in &data.diagonal {
            if let Some(d) = diagonal
                .iter_mut()
                .find(|d| d.row == c.row && d.column == c.column)
            {
                d.value = Some(c.value);
            }
        }
        let mut diagonal_of_column = vec![None; data.n_emission()];
        for (p, d) in diagonal.iter().enumerate() {
            diagonal_of_column[d.column] = Some(p);
        }
        let mut row_weight = vec![0.0f64; data.n_excitation()];
        let patches: Vec<PatchLight> = lights
            .iter()
            .zip(reference)
            .map(|(light, xyz)| {
                let pc = PatchColorimeter::cached(light, &data.excitation_nm, &data.emission_nm);
                let (light_weights, reflected, emitted, _, scale) = pc.weights();
                let peak = light_weights.iter().cloned().fold(0.0, f64::max);
                if peak > 0.0 {
                    for (w, lw) in row_weight.iter_mut().zip(light_weights) {
                        *w = w.max(lw / peak);
                    }
                }
                let jacobian = lab_jacobian(*xyz, pc.white);
                let project = |weights: &[Xyz], channel: usize| -> Vec<f64> {
                    weights
                        .iter()
                        .map(|w| scale * (0..3).map(|x| jacobian[channel][x] * w[x]).sum::<f64>())
                        .collect()
                };
                let emitted = [0, 1, 2].map(|c| project(emitted, c));
                let emitted_by_column = [0, 1, 2].map(|c| {
                    emitted[c]
                        .iter()
                        .zip(&density_factor)
                        .map(|(e, f)| e * f)
                        .collect()
                });
                PatchLight {
                    light_weights: light_weights.to_vec(),
                    emitted,
                    reflected: [0, 1, 2].map(|c| project(reflected, c)),
                    emitted_by_column,
                }
            })
            .collect();
        if lights.is_empty() {
            row_weight.iter_mut().for_each(|w| *w = 1.0);
        }
        let row_weight = row_weight.iter().map(|w| w.max(ROW_WEIGHT_FLOOR)).collect();
        let n_em = data.n_emission();
        let mut cell_mask = vec![0.0; data.n_excitation() * n_em];
        let mut cell_value = vec![0.0; data.n_excitation() * n_em];
        for c in &data.off_diagonal {
            cell_mask[c.row * n_em + c.column] = 1.0;
            cell_value[c.row * n_em + c.column] = c.value;
        }
        let excitation_u: Vec<f64> = data
            .excitation_nm
            .iter()
            .map(|&l| domain.coordinate(l))
            .collect();
        let emission_u: Vec<f64> = data
            .emission_nm
            .iter()
            .map(|&l| domain.coordinate(l))
            .collect();
        let layout = Layout::new(spec);
        let mut reflectance_basis = Vec::new();
        if let ReflectanceForm::Polynomial(_) = spec.reflectance {
            for d in &diagonal {
                legendre(d.x, layout.reflectance().len(), |_, pn| {
                    reflectance_basis.push(pn)
                });
            }
        }
        let mut problem = Problem {
            data,
            layout,
            excitation_floor: WidthFloor::new(&excitation_u),
            emission_floor: WidthFloor::new(&emission_u),
            excitation_u,
            emission_u,
            column_factor,
            density_factor,
            diagonal,
            diagonal_of_column,
            row_weight,
            cell_mask,
            cell_value,
            patches,
            colour_weight,
            light_weight: vec![1.0; lights.len()],
            reflectance_support,
            reflectance_basis,
            band_box: Vec::new(),
        };
        problem.band_box = problem.build_band_box();
        problem
    }

    /// Scales each light's colour term by `weights` (one per light, in the order given to
    /// [`Problem::new`]); an empty slice leaves every light at 1.
    pub fn with_light_weights(mut self, weights: &[f64]) -> Self {
        if weights.len() == self.light_weight.len() {
            self.light_weight = weights.to_vec();
        }
        self
    }

    /// Σk κ_k·a_k·m_k at diagonal sample `d`: one minus the diagonal's cap (Σk κ_k·a_k
    /// in the energy form).
    pub(super) fn absorbed(&self, m: &GridModel, d: &DiagonalSample) -> f64 {
        (0..m.kappa.len())
            .map(|k| m.kappa[k] * m.absorption[k][d.row] * m.cap_factor[k][d.row])
            .sum()
    }

    /// The fluorescent model value of cell (i, j).
    pub(super) fn fluorescence(&self, m: &GridModel, i: usize, j: usize) -> f64 {
        let u = self.column_factor[j];
        (0..m.kappa.len())
            .map(|k| {
                m.scale[k] * m.absorption[k][i] * m.excitation_factor[k][i] * m.emission[k][j] * u
            })
            .sum()
    }

    /// The diagonal d_j at sample `p` and, for a tabulated reflectance, how it was
    /// projected (`None` for a polynomial reflectance).
    pub fn diagonal_value(&self, m: &GridModel, p: usize) -> (f64, Option<Projection>) {
        let d = &self.diagonal[p];
        let cap = 1.0 - self.absorbed(m, d);
        match self.layout.spec.reflectance {
            ReflectanceForm::Polynomial(_) => (cap * m.reflectance[p], None),
            ReflectanceForm::Tabulated => {
                let Some(value) = d.value else {
                    return (f64::NAN, Some(Projection::Unmeasured));
                };
                let raw = value - self.fluorescence(m, d.row, d.column);
                if raw < 0.0 {
                    (0.0, Some(Projection::AtZero))
                } else if raw > cap {
                    (cap, Some(Projection::AtCap))
                } else {
                    (raw, Some(Projection::Free))
                }
            }
        }
    }

    /// The objective and its gradient.
    pub fn cost_gradient(&self, theta: &[f64]) -> (f64, Vec<f64>) {
        // The dense cell loops are a third of a search (perf on CIBA12): compiled for
        // AVX2 as well and chosen at run time, as the grid objective's are. Without FMA
        // contraction (not enabled) and with the loops' order of additions fixed, both
        // builds give the same bits.
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2, checked just above.
            return unsafe { self.cost_gradient_avx2(theta) };
        }
        self.cost_gradient_body(theta)
    }

    /// [`Problem::cost_gradient`] compiled for AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn cost_gradient_avx2(&self, theta: &[f64]) -> (f64, Vec<f64>) {
        self.cost_gradient_body(theta)
    }

    /// The body of [`Problem::cost_gradient`], inlined into each build.
    // The adjoint loops index several parallel per-component arrays by the same sample.
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn cost_gradient_body(&self, theta: &[f64]) -> (f64, Vec<f64>) {
        let data = self.data;
        let layout = &self.layout;
        let mut workspace = scratch::take();
        let Workspace {
            model: m,
            weighted_emission,
            matrix: model,
            diagonal: diag,
            column_sum,
            patch,
            row_square,
            q,
            h,
            scale_bar,
            a_bar,
            e_bar,
            kappa_bar,
            mean_bar,
            r_bar,
            light_weights,
            column_adjoint,
            row_dot,
            g_bar,
        } = &mut *workspace;
        self.fill_grid_model(theta, m);
        let k_count = m.kappa.len();
        let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
        let n_lights = self.patches.len();
        // The model matrix, dense: F_ij = Σk s_k·a_ik·(e_jk·u_j).
        weighted_emission.resize_with(k_count, Vec::new);
        for (weighted, e) in weighted_emission.iter_mut().zip(&m.emission) {
            weighted.clear();
            weighted.extend(e.iter().zip(&self.column_factor).map(|(e, u)| e * u));
        }
        // Without a zeroed buffer first: 0 + x is x, so the first component's terms are
        // written as the sum's first additions would leave them.
        model.clear();
        match weighted_emission.first() {
            Some(first) => {
                for i in 0..n_ex {
                    let sa = m.scale[0] * m.absorption[0][i] * m.excitation_factor[0][i];
                    model.extend(first.iter().map(|ue| 0.0 + sa * ue));
                }
            }
            None => model.resize(n_ex * n_em, 0.0),
        }
        for k in 1..k_count {
            for (i, row) in model.chunks_exact_mut(n_em).enumerate() {
                let sa = m.scale[k] * m.absorption[k][i] * m.excitation_factor[k][i];
                for (f, ue) in row.iter_mut().zip(&weighted_emission[k]) {
                    *f += sa * ue;
                }
            }
        }
        diag.clear();
        diag.extend((0..self.diagonal.len()).map(|p| {
            let (d, projection) = self.diagonal_value(m, p);
            let s = &self.diagonal[p];
            let residual = match (s.value, projection) {
                (None, _) | (_, Some(Projection::Free)) => 0.0,
                (Some(v), _) => v - model[s.row * n_em + s.column] - d,
            };
            (residual, projection)
        }));
        // Residuals (0 outside the cells), and the patch rows they add up to. The model's
        // buffer becomes the residuals', then the adjoints' (one matrix in memory for the
        // three).
        let residual = model;
        for ((f, v), mask) in residual
            .iter_mut()
            .zip(&self.cell_value)
            .zip(&self.cell_mask)
        {
            *f = mask * (v - *f);
        }
        // Column sums Σ_i L_i·r_ij per light, then ΔLab per light.
        scratch::zeroed(column_sum, n_lights * n_em);
        for (i, row) in residual.chunks_exact(n_em).enumerate() {
            for (light, sums) in self.patches.iter().zip(column_sum.chunks_exact_mut(n_em)) {
                let w = light.light_weights[i];
                for (s, r) in sums.iter_mut().zip(row) {
                    *s += w * r;
                }
            }
        }
        // Each light and channel's sum over the columns in column order, the twelve
        // sums advancing together: one after another, each was a chain of dependent
        // additions (perf annotate).
        scratch::zeroed(patch, n_lights * 3);
        for j in 0..n_em {
            let diagonal = self.diagonal_of_column[j].map(|p| diag[p].0);
            for (l, light) in self.patches.iter().enumerate() {
                let sum = column_sum[l * n_em + j];
                for channel in 0..3 {
                    let v = &mut patch[l * 3 + channel];
                    *v += light.emitted_by_column[channel][j] * sum;
                    if let Some(d) = diagonal {
                        *v += light.reflected[channel][j] * d;
                    }
                }
            }
        }
        let mut cost = 0.0;
        scratch::zeroed(row_square, n_ex);
        row_squares(residual, n_em, row_square);
        for (square, w) in row_square.iter().zip(&self.row_weight) {
            cost += 0.5 * w * square;
        }
        for (s, (r, _)) in self.diagonal.iter().zip(diag.iter()) {
            cost += 0.5 * self.row_weight[s.row] * r * r;
        }
        // One sum in patch order, each term scaled by its light's weight (exactly 1 unless
        // set, so the default objective is bit for bit what it was).
        cost += 0.5
            * self.colour_weight
            * patch
                .iter()
                .enumerate()
                .map(|(k, p)| self.light_weight[k / 3] * p * p)
                .sum::<f64>();
        // The colour term's pull on residuals of column j: q (reradiated) and h (diagonal).
        // q is kept by quads of columns, each quad's lights side by side (lanes past the
        // last column 0), as the adjoint loop below reads it; without lights, one quad of
        // zeros per quad of columns.
        let quad_len = 4 * n_lights.max(1);
        scratch::zeroed(q, n_em.div_ceil(4) * quad_len);
        scratch::zeroed(h, n_lights * n_em);
        for (l, light) in self.patches.iter().enumerate() {
            for j in 0..n_em {
                let (mut qe, mut hr) = (0.0, 0.0);
                for channel in 0..3 {
                    let p = self.colour_weight * self.light_weight[l] * patch[l * 3 + channel];
                    qe += p * light.emitted[channel][j];
                    hr += p * light.reflected[channel][j];
                }
                q[j / 4 * quad_len + 4 * l + j % 4] = qe * self.density_factor[j];
                h[l * n_em + j] = hr;
            }
        }

        // Adjoints: ∂cost/∂F for every cell (F̄ = −δ), gathered densely, then through
        // the factors (two matrix-vector products per component).
        scratch::zeroed(scale_bar, k_count);
        scratch::zeroed_rows(a_bar, k_count, n_ex);
        scratch::zeroed_rows(e_bar, k_count, n_em);
        scratch::zeroed(kappa_bar, k_count);
        // ∂cost/∂λ̄e_k through the photon form's row and cap factors.
        scratch::zeroed(mean_bar, k_count);
        scratch::zeroed(r_bar, self.diagonal.len());
        // Written row by row as 0 − δ (what subtracting from a zeroed buffer leaves), over
        // the residuals, which nothing reads after.
        let f_bar = residual;
        scratch::zeroed(light_weights, n_lights);
        for (i, (row, mask_row)) in f_bar
            .chunks_exact_mut(n_em)
            .zip(self.cell_mask.chunks_exact(n_em))
            .enumerate()
        {
            // δ_ij = w_i·r_ij + Σ_l L_li·q_lj on the cells. The lights' pull is summed in
            // registers four columns at a time, from 0 in light order as a zeroed row
            // buffer summed it (which made four passes over memory per row); the quads
            // of q side by side keep the loads contiguous and free of bounds checks.
            for (w, light) in light_weights.iter_mut().zip(&self.patches) {
                *w = light.light_weights[i];
            }
            let w = self.row_weight[i];
            let (row_quads, row_tail) = row.as_chunks_mut::<4>();
            let (mask_quads, mask_tail) = mask_row.as_chunks::<4>();
            let mut q_quads = q.chunks_exact(quad_len);
            for ((f, mask), q_quad) in row_quads.iter_mut().zip(mask_quads).zip(&mut q_quads) {
                let pull = light_pull(light_weights, q_quad);
                let old = *f;
                *f = std::array::from_fn(|t| 0.0 - mask[t] * (w * old[t] + pull[t]));
            }
            if let Some(q_quad) = q_quads.next() {
                let pull = light_pull(light_weights, q_quad);
                for ((f, mask), pull) in row_tail.iter_mut().zip(mask_tail).zip(pull) {
                    *f = 0.0 - mask * (w * *f + pull);
                }
            }
        }
        for (p, (s, (r, projection))) in self.diagonal.iter().zip(diag.iter()).enumerate() {
            if s.value.is_none() || *projection == Some(Projection::Free) {
                continue;
            }
            let mut delta = self.row_weight[s.row] * r;
            for l in 0..n_lights {
                delta += h[l * n_em + s.column];
            }
            // r = M − F − d: F̄ = −δ; d̄ = −δ.
            f_bar[s.row * n_em + s.column] -= delta;
            let d_bar = -delta;
            let absorbed_bar = match projection {
                None => {
                    let cap = 1.0 - self.absorbed(m, s);
                    r_bar[p] += d_bar * cap;
                    -d_bar * m.reflectance[p]
                }
                Some(Projection::AtCap) => -d_bar,
                _ => 0.0,
            };
            for k in 0..k_count {
                let (a, cf) = (m.absorption[k][s.row], m.cap_factor[k][s.row]);
                kappa_bar[k] += absorbed_bar * a * cf;
                a_bar[k][s.row] += absorbed_bar * m.kappa[k] * cf;
                if m.excitation_factor[k][s.row] > 1.0 {
                    // m = λ/λ̄e: ∂m/∂λ̄e = −m/λ̄e.
                    mean_bar[k] -= absorbed_bar * m.kappa[k] * a * cf / m.emission_mean_nm[k];
                }
            }
        }

        scratch::zeroed(row_dot, n_ex);
        for k in 0..k_count {
            scratch::zeroed(column_adjoint, n_em);
            row_dots(f_bar, &weighted_emission[k], row_dot);
            for (i, row) in f_bar.chunks_exact(n_em).enumerate() {
                let x = m.excitation_factor[k][i];
                let a = m.absorption[k][i] * x;
                let t = row_dot[i];
                for (fb, v) in row.iter().zip(column_adjoint.iter_mut()) {
                    *v += fb * a;
                }
                a_bar[k][i] += m.scale[k] * x * t;
                scale_bar[k] += a * t;
                if self.layout.spec.photon() {
                    // x = λi/λ̄e: ∂x/∂λ̄e = −x/λ̄e.
                    mean_bar[k] -= m.scale[k] * a * t / m.emission_mean_nm[k];
                }
            }
            for ((eb, v), u) in e_bar[k]
                .iter_mut()
                .zip(column_adjoint.iter())
                .zip(&self.column_factor)
            {
                *eb += m.scale[k] * u * v;
            }
        }

        // Σk κ_k·a_ik·m_ik ≤ 1 on the excitation grid (several components, or the photon
        // form, whose m exceeds 1 where a component absorbs above its mean emission).
        if k_count > 1 || self.layout.spec.photon() {
            for i in 0..n_ex {
                let excess: f64 = (0..k_count)
                    .map(|k| m.kappa[k] * m.absorption[k][i] * m.cap_factor[k][i])
                    .sum::<f64>()
                    - 1.0;
                if excess > 0.0 {
                    cost += 0.5 * ABSORPTION_PENALTY * excess * excess;
                    for k in 0..k_count {
                        let (a, cf) = (m.absorption[k][i], m.cap_factor[k][i]);
                        let p = ABSORPTION_PENALTY * excess;
                        kappa_bar[k] += p * a * cf;
                        a_bar[k][i] += p * m.kappa[k] * cf;
                        if m.excitation_factor[k][i] > 1.0 {
                            mean_bar[k] -= p * m.kappa[k] * a * cf / m.emission_mean_nm[k];
                        }
                    }
                }
            }
        }
        let mut gradient = vec![0.0; layout.len];
        for k in 0..k_count {
            // s = κ/(γ·S): through κ, S and γ (γ = λ̄e/λmin when photon-limited).
            kappa_bar[k] += scale_bar[k] / (m.photon_factor[k] * m.normaliser[k]);
            let s = m.scale[k];
            let photon_limited = !self.layout.spec.photon()
                && m.emission_mean_nm[k] / m.shortest_absorbed_nm[k] > 1.0;
            let gauge_s = m.normaliser[k] - 1.0;
            for j in 0..n_em {
                let w = data.emission_bin_widths[j];
                let mut d_scale = -s * w / m.normaliser[k];
                // ∂λ̄e/∂e_j = w_j·(λ_j − λ̄e)/S.
                let d_mean = w * (data.emission_nm[j] - m.emission_mean_nm[k]) / m.normaliser[k];
                if photon_limited {
                    let d_gamma = d_mean / m.shortest_absorbed_nm[k];
                    d_scale -= s * d_gamma / m.photon_factor[k];
                }
                e_bar[k][j] += scale_bar[k] * d_scale
                    + mean_bar[k] * d_mean
                    + HEIGHT_GAUGE_WEIGHT * gauge_s * w;
            }
            // a = g/G with G the grid peak.
            let peak = m.absorption_peak[k];
            g_bar.clear();
            g_bar.extend(a_bar[k].iter().map(|ab| ab / peak));
            let through_peak: f64 = a_bar[k]
                .iter()
                .zip(&m.absorption[k])
                .map(|(ab, a)| ab * a)
                .sum::<f64>()
                / peak;
            g_bar[m.peak_index[k]] += -through_peak + HEIGHT_GAUGE_WEIGHT * (peak - 1.0);
            let ar = layout.absorption(k);
            for (gb, g) in g_bar
                .iter()
                .zip(m.absorption_jacobian[k].chunks_exact(ar.len().max(1)))
            {
                for (t, gp) in gradient[ar.clone()].iter_mut().zip(g) {
                    *t += gb * gp;
                }
            }
            let er = layout.emission(k);
            for (eb, g) in e_bar[k]
                .iter()
                .zip(m.emission_jacobian[k].chunks_exact(er.len().max(1)))
            {
                for (t, gp) in gradient[er.clone()].iter_mut().zip(g) {
                    *t += eb * gp;
                }
            }
            cost += 0.5 * HEIGHT_GAUGE_WEIGHT * (gauge_s * gauge_s + (peak - 1.0).powi(2));
        }
        // κ_k = sin²t_k.
        for k in 0..k_count {
            gradient[k] = kappa_bar[k] * (2.0 * theta[k]).sin();
        }
        cost += self.band_penalty(theta, &mut gradient);
        if let ReflectanceForm::Polynomial(_) = layout.spec.reflectance {
            let range = layout.reflectance();
            let count = range.len();
            for (p, basis) in self
                .reflectance_basis
                .chunks_exact(count.max(1))
                .enumerate()
            {
                if r_bar[p] == 0.0 {
                    continue;
                }
                let r = m.reflectance[p];
                let dp = r_bar[p] * r * (1.0 - r);
                for (g, pn) in gradient[range.clone()].iter_mut().zip(basis) {
                    *g += dp * pn;
                }
            }
        }
        scratch::give_back(workspace);
        (cost, gradient)
    }

    /// Moves band parameters into the box the objective penalises leaving (for starts).
    pub fn clamp_to_box(&self, theta: &mut [f64]) {
        for &(n, (low, high)) in &self.band_box {
            let p = &mut theta[n];
            *p = if p.is_finite() {
                p.clamp(low, high)
            } else {
                0.5 * (low + high)
            };
        }
    }

    /// (parameter index, lower, upper) for every band parameter: centres within half the
    /// measured span beyond its ends, width parameters below ln(twice the span), heights
    /// below e⁶. The widths' lower end only stops θ drifting where the hard floor
    /// ([`WidthFloor`]) alone sets the width (e^θ under 1 % of the floor). Computed once,
    /// in [`Problem::new`] (the `band_box` field).
    fn build_band_box(&self) -> Vec<(usize, (f64, f64))> {
        let mut boxes = Vec::new();
        for k in 0..self.layout.spec.components {
            for (range, grid, floor) in [
                (
                    self.layout.absorption(k),
                    &self.excitation_u,
                    &self.excitation_floor,
                ),
                (
                    self.layout.emission(k),
                    &self.emission_u,
                    &self.emission_floor,
                ),
            ] {
                let lo = grid.iter().cloned().fold(f64::INFINITY, f64::min);
                let hi = grid.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let span = (hi - lo).max(1e-6);
                let bounds = [
                    (-30.0, 6.0),
                    (lo - 0.5 * span, hi + 0.5 * span),
                    ((0.01 * floor.smallest()).ln(), (2.0 * span).ln()),
                ];
                for band in range.step_by(PARAMS_PER_BAND) {
                    for (n, b) in bounds.iter().enumerate() {
                        boxes.push((band + n, *b));
                    }
                }
            }
        }
        boxes
    }

    /// Component `k`'s absorption and emission bands in `theta` as Gaussian parameters
    /// (ln height, centre, ln width), their widths held above the floor.
    pub fn component_bands(&self, theta: &[f64], k: usize) -> [Vec<f64>; 2] {
        [
            self.excitation_floor
                .widen(&theta[self.layout.absorption(k)])
                .0,
            self.emission_floor.widen(&theta[self.layout.emission(k)]).0,
        ]
    }

    /// Solver parameters of absorption bands given as Gaussian parameters (ln height,
    /// centre, ln width): bands narrower than the floor start just above it.
    pub fn absorption_solver_params(&self, gaussian: &[f64]) -> Vec<f64> {
        self.excitation_floor.solver_params(gaussian)
    }

    /// Solver parameters of emission bands given as Gaussian parameters (see
    /// [`Problem::absorption_solver_params`]).
    pub fn emission_solver_params(&self, gaussian: &[f64]) -> Vec<f64> {
        self.emission_floor.solver_params(gaussian)
    }

    /// The soft box on band parameters (the `band_box` field). Adds its gradient to
    /// `gradient` and returns its cost.
    pub(super) fn band_penalty(&self, theta: &[f64], gradient: &mut [f64]) -> f64 {
        let mut cost = 0.0;
        for &(n, (low, high)) in &self.band_box {
            let p = theta[n];
            let outside = if p < low {
                p - low
            } else if p > high {
                p - high
            } else {
                continue;
            };
            cost += 0.5 * BAND_BOX_PENALTY * outside * outside;
            gradient[n] += BAND_BOX_PENALTY * outside;
        }
        cost
    }

    /// The matrix-residual part of the cost alone (unweighted ½Σr² over the data cells),
    /// for the information criterion.
    pub fn residual_sum_of_squares(&self, theta: &[f64]) -> f64 {
        let m = self.grid_model(theta);
        let mut rss = 0.0;
        for c in &self.data.off_diagonal {
            rss += (c.value - self.fluorescence(&m, c.row, c.column)).powi(2);
        }
        for p in 0..self.diagonal.len() {
            let s = &self.diagonal[p];
            if let Some(v) = s.value {
                let (d, _) = self.diagonal_value(&m, p);
                if d.is_finite() {
                    rss += (v - self.fluorescence(&m, s.row, s.column) - d).powi(2);
                }
            }
        }
        rss
    }

    /// The central-difference gradient of the cost (to test [`Problem::cost_gradient`]).
    pub fn numerical_gradient(&self, theta: &[f64], step: f64) -> Vec<f64> {
        (0..theta.len())
            .map(|n| {
                let mut plus = theta.to_vec();
                let mut minus = theta.to_vec();
                plus[n] += step;
                minus[n] -= step;
                (self.cost_gradient(&plus).0 - self.cost_gradient(&minus).0) / (2.0 * step)
            })
            .collect()
    }

    /// The diagonal sample positions (row, column) in order.
    pub fn diagonal_positions(&self) -> Vec<(usize, usize)> {
        self.diagonal.iter().map(|d| (d.row, d.column)).collect()
    }
}

/// Σ_l w_l·q_l over one quad of columns, from 0 in light order: `q_quad` holds each
/// light's four values in turn.
#[inline(always)]
fn light_pull(light_weights: &[f64], q_quad: &[f64]) -> [f64; 4] {
    let mut pull = [0.0; 4];
    for (wl, q4) in light_weights.iter().zip(q_quad.as_chunks::<4>().0) {
        for t in 0..4 {
            pull[t] += wl * q4[t];
        }
    }
    pull
}
