//! The grating's second-order image of the emission: an emission monochromator set to λo
//! also passes light of λo/2 in its second order, so a component with first-order
//! emission e(λ) is seen as `e(λo) + G(λo)·e(λo/2)`, with one non-negative gain G(λo)
//! (second-order efficiency over first-order, with any emission correction the data
//! carry) shared by every component.
//!
//! G is piecewise linear in λo on nodes [`NODE_SPACING_NM`] apart over the rows whose
//! half lies on the emission grid (the image rows), and zero elsewhere. The data alone do
//! not fix it: any G that leaves every first-order emission non-negative fits the cells
//! alike (the image and the first-order emission at λo are one number per component and
//! row). It is identified by the prior that a component's first-order emission in the
//! image rows is what the image cannot explain: G is the lower envelope of the fitted
//! ratios (effective emission at λo over first-order emission at λo/2), an asymmetric
//! least-squares fit ([`ENVELOPE_WEIGHT`] for components above it) weighted by how much
//! each component's image weighs in the data.

/// Spacing of G's nodes (nm).
pub const NODE_SPACING_NM: f64 = 30.0;
/// Weight of a component whose effective emission lies above `G·image` (it may hold
/// first-order emission there) relative to one below it (negative first-order emission)
/// in the envelope fit of G.
pub const ENVELOPE_WEIGHT: f64 = 0.05;
/// Reweighting passes of the envelope fit.
const ENVELOPE_PASSES: usize = 30;
/// Coordinate-descent sweeps of each envelope least-squares solve.
const NODE_SWEEPS: usize = 200;

/// The image operator on one emission grid and G's nodes.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Per emission index o: the cells of λo/2 on the grid and their linear-interpolation
    /// weights (empty where λo/2 lies off the grid).
    sources: Vec<Vec<(usize, f64)>>,
    /// Per emission index j: the image rows it feeds, with the same weights.
    targets: Vec<Vec<(usize, f64)>>,
    /// G's nodes (nm).
    nodes_nm: Vec<f64>,
    /// Per emission index: the nodes whose hat functions cover it, with their weights.
    hats: Vec<Vec<(usize, f64)>>,
}

impl Image {
    /// The operator on emission grid `em_nm` (increasing); `None` when fewer than two
    /// emission wavelengths have their half on the grid (no image to fit).
    pub fn new(em_nm: &[f64]) -> Option<Image> {
        let n = em_nm.len();
        if n < 2 || em_nm.windows(2).any(|w| w[1] <= w[0] || !w[0].is_finite()) {
            return None;
        }
        let (lo, hi) = (em_nm[0], em_nm[n - 1]);
        let mut sources = vec![Vec::new(); n];
        let mut targets = vec![Vec::new(); n];
        for (o, &l) in em_nm.iter().enumerate() {
            let half = l / 2.0;
            if half < lo - 1e-9 || half > hi + 1e-9 {
                continue;
            }
            let j = em_nm.partition_point(|&x| x <= half + 1e-9).clamp(1, n - 1);
            let (a, b) = (em_nm[j - 1], em_nm[j]);
            let t = ((half - a) / (b - a)).clamp(0.0, 1.0);
            for (src, w) in [(j - 1, 1.0 - t), (j, t)] {
                if w > 1e-12 && src < o {
                    sources[o].push((src, w));
                    targets[src].push((o, w));
                }
            }
        }
        let rows: Vec<usize> = (0..n).filter(|&o| !sources[o].is_empty()).collect();
        if rows.len() < 2 {
            return None;
        }
        let (first, last) = (em_nm[rows[0]], em_nm[rows[rows.len() - 1]]);
        let count = ((last - first) / NODE_SPACING_NM).round().max(1.0) as usize;
        let nodes_nm: Vec<f64> = (0..=count)
            .map(|i| first + (last - first) * i as f64 / count as f64)
            .collect();
        let hats = (0..n)
            .map(|o| {
                if sources[o].is_empty() {
                    return Vec::new();
                }
                let l = em_nm[o];
                let i = nodes_nm
                    .partition_point(|&x| x <= l)
                    .clamp(1, nodes_nm.len() - 1);
                let t = ((l - nodes_nm[i - 1]) / (nodes_nm[i] - nodes_nm[i - 1])).clamp(0.0, 1.0);
                vec![(i - 1, 1.0 - t), (i, t)]
            })
            .collect();
        Some(Image {
            sources,
            targets,
            nodes_nm,
            hats,
        })
    }

    /// Emission wavelengths of the grid it was built on.
    pub fn len(&self) -> usize {
        self.sources.len()
    }

    /// Whether the grid is empty (never: [`Image::new`] needs two image rows).
    pub fn is_empty(&self) -> bool {
        self.sources.is_empty()
    }

    /// G's nodes (nm).
    pub fn nodes_nm(&self) -> &[f64] {
        &self.nodes_nm
    }

    /// G at every emission index from its node values `g`.
    pub fn gain(&self, g: &[f64]) -> Vec<f64> {
        self.hats
            .iter()
            .map(|h| h.iter().map(|&(n, w)| w * g[n]).sum())
            .collect()
    }

    /// The image `Σ w·e(λo/2)` of one spectrum `e` (per emission index) at row `o`.
    fn image_at(&self, e: &[f64], o: usize) -> f64 {
        self.sources[o].iter().map(|&(j, w)| w * e[j]).sum()
    }

    /// The effective emission `e(λo) + G(λo)·e(λo/2)` of one first-order spectrum, with G
    /// per emission index `gain`.
    pub fn effective(&self, e: &[f64], gain: &[f64]) -> Vec<f64> {
        (0..e.len())
            .map(|o| e[o] + gain[o] * self.image_at(e, o))
            .collect()
    }

    /// The first-order spectrum of an effective one (the inverse of [`Image::effective`],
    /// from short to long wavelengths), clipped at zero.
    pub fn first_order(&self, f: &[f64], gain: &[f64]) -> Vec<f64> {
        let mut e = f.to_vec();
        for o in 0..e.len() {
            if !self.sources[o].is_empty() {
                e[o] = (f[o] - gain[o] * self.image_at(&e, o)).max(0.0);
            }
        }
        e
    }

    /// One projected update of the first-order emission with the effective emission
    /// `rows[em·K + c]` (K components, row-major), given each row's Gram matrix
    /// `grams[em·K² ..]` and right-hand side `rhs[em·K + c]` of the effective emission's
    /// normal equations: coordinate descent on the first-order cells (≥ 0), each moving
    /// its own row and its image rows. `rows` is replaced by the new effective emission.
    pub fn update_rows(
        &self,
        rows: &mut [f64],
        k: usize,
        rhs: &[f64],
        grams: &[f64],
        gain: &[f64],
        sweeps: usize,
    ) {
        let n = rows.len() / k.max(1);
        let mut first = vec![0.0; rows.len()];
        for c in 0..k {
            let f: Vec<f64> = (0..n).map(|i| rows[i * k + c]).collect();
            for (i, v) in self.first_order(&f, gain).into_iter().enumerate() {
                first[i * k + c] = v;
            }
        }
        for c in 0..k {
            let e: Vec<f64> = (0..n).map(|i| first[i * k + c]).collect();
            for (i, v) in self.effective(&e, gain).into_iter().enumerate() {
                rows[i * k + c] = v;
            }
        }
        let mut touched: Vec<(usize, f64)> = Vec::new();
        for _ in 0..sweeps {
            for j in 0..n {
                touched.clear();
                touched.push((j, 1.0));
                touched.extend(self.targets[j].iter().map(|&(o, w)| (o, w * gain[o])));
                for c in 0..k {
                    let (mut gradient, mut curvature) = (0.0, 0.0);
                    for &(r, a) in &touched {
                        if a == 0.0 {
                            continue;
                        }
                        let g = &grams[r * k * k + c * k..r * k * k + (c + 1) * k];
                        let hf: f64 = g
                            .iter()
                            .zip(&rows[r * k..(r + 1) * k])
                            .map(|(h, f)| h * f)
                            .sum();
                        gradient += a * (hf - rhs[r * k + c]);
                        curvature += a * a * g[c];
                    }
                    if curvature <= 0.0 {
                        continue;
                    }
                    let old = first[j * k + c];
                    let new = (old - gradient / curvature).max(0.0);
                    let step = new - old;
                    if step != 0.0 {
                        first[j * k + c] = new;
                        for &(r, a) in &touched {
                            rows[r * k + c] += a * step;
                        }
                    }
                }
            }
        }
    }

    /// G's node values fitted to the effective emission `rows[em·K + c]` as the lower
    /// envelope of the components' ratios (see the module doc), each row and component
    /// weighted by `weights[em·K + c]` (the diagonal of its Gram matrix); `gain` is the
    /// current G per emission index (it fixes the first-order emission the image is made
    /// of where image rows feed image rows).
    pub fn fit_gain(&self, rows: &[f64], k: usize, weights: &[f64], gain: &[f64]) -> Vec<f64> {
        let n = rows.len() / k.max(1);
        let nodes = self.nodes_nm.len();
        // Per image row and component: effective emission, image, weight.
        let mut cells: Vec<(usize, f64, f64, f64)> = Vec::new();
        for c in 0..k {
            let f: Vec<f64> = (0..n).map(|i| rows[i * k + c]).collect();
            let e = self.first_order(&f, gain);
            for o in 0..n {
                if self.sources[o].is_empty() {
                    continue;
                }
                let image = self.image_at(&e, o);
                let w = weights[o * k + c];
                if image > 0.0 && w > 0.0 && w.is_finite() {
                    cells.push((o, f[o], image, w));
                }
            }
        }
        let mut g = vec![0.0; nodes];
        if cells.is_empty() {
            return g;
        }
        let mut below = vec![true; cells.len()];
        for _ in 0..ENVELOPE_PASSES {
            let mut q = vec![0.0; nodes * nodes];
            let mut b = vec![0.0; nodes];
            for (&(o, f, image, w), &under) in cells.iter().zip(&below) {
                let w = if under { w } else { w * ENVELOPE_WEIGHT };
                for &(a, ha) in &self.hats[o] {
                    b[a] += w * image * f * ha;
                    for &(bn, hb) in &self.hats[o] {
                        q[a * nodes + bn] += w * image * image * ha * hb;
                    }
                }
            }
            for _ in 0..NODE_SWEEPS {
                for a in 0..nodes {
                    let d = q[a * nodes + a];
                    if d <= 0.0 {
                        continue;
                    }
                    let predicted: f64 = (0..nodes).map(|m| q[a * nodes + m] * g[m]).sum();
                    g[a] = (g[a] + (b[a] - predicted) / d).max(0.0);
                }
            }
            let gain = self.gain(&g);
            let next: Vec<bool> = cells
                .iter()
                .map(|&(o, f, image, _)| f < gain[o] * image)
                .collect();
            if next == below {
                break;
            }
            below = next;
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a 1 nm grid the image of λo = 2λ is e(λ), and of odd λo the mean of its two
    /// neighbours; first_order undoes effective.
    #[test]
    fn image_and_inverse() {
        let em: Vec<f64> = (0..=450).map(|i| 250.0 + i as f64).collect();
        let image = Image::new(&em).unwrap();
        assert_eq!(image.nodes_nm()[0], 500.0);
        assert_eq!(*image.nodes_nm().last().unwrap(), 700.0);
        let e: Vec<f64> = em
            .iter()
            .map(|&l| (-(l - 300.0_f64).powi(2) / 200.0).exp())
            .collect();
        let g = vec![0.5; image.nodes_nm().len()];
        let gain = image.gain(&g);
        let f = image.effective(&e, &gain);
        assert!((f[350] - (e[350] + 0.5 * e[50])).abs() < 1e-12);
        assert!((f[351] - (e[351] + 0.25 * (e[50] + e[51]))).abs() < 1e-12);
        assert_eq!(f[100], e[100]);
        let back = image.first_order(&f, &gain);
        assert!(back.iter().zip(&e).all(|(a, b)| (a - b).abs() < 1e-12));
        // Components with no first-order emission in the image rows give G back.
        let truth: Vec<f64> = (0..image.nodes_nm().len())
            .map(|i| 0.8 - 0.05 * i as f64)
            .collect();
        let gain = image.gain(&truth);
        let k = 2;
        let mut rows = vec![0.0; em.len() * k];
        for c in 0..k {
            let e: Vec<f64> = em
                .iter()
                .map(|&l| (-(l - 290.0 - 40.0 * c as f64).powi(2) / 300.0).exp())
                .collect();
            for (i, v) in image.effective(&e, &gain).into_iter().enumerate() {
                rows[i * k + c] = v;
            }
        }
        let fitted = image.fit_gain(&rows, k, &vec![1.0; rows.len()], &vec![0.0; em.len()]);
        for (a, b) in fitted.iter().zip(&truth) {
            assert!((a - b).abs() < 1e-6, "{fitted:?}");
        }
    }

    /// No image rows on a grid shorter than an octave.
    #[test]
    fn short_grids_have_no_image() {
        let em: Vec<f64> = (0..100).map(|i| 300.0 + 2.0 * i as f64).collect();
        assert!(Image::new(&em).is_none());
    }
}
