//! Pruning the grid model's samples the data do not support.
//!
//! Every absorption and emission sample of the grid model is free and non-negative. Where
//! the truth is zero (rows far past the emission, columns far past the fluorescence) a
//! least-squares estimate of pure noise is clipped at 0 on one side and kept on the other:
//! its mean is +0.4 σ of the estimate in every such row, and the positive values add up
//! coherently in a colour. Under A, whose red rows carry most of the light, a fit of
//! matrix noise σ = 3·10⁻³ gained spurious fluorescence worth ΔE2000 3.9 that way
//! (`fluorite class`, case147). Runs of samples whose signed estimates are below
//! [`PRUNE_SIGNIFICANCE`] σ one by one and together are indistinguishable from the
//! noise's positive half and are set to zero.

use super::data::FitData;
use super::objective::Objective;
use super::representation::GridSpectra;

/// Significance (in σ of the estimate) below which a sample, and a run of such samples
/// taken together, counts as the noise's doing. Pure noise passes 2 σ in 2.3 % of samples.
pub const PRUNE_SIGNIFICANCE: f64 = 2.0;

/// How many samples were pruned.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Pruned {
    /// Absorption samples set to zero.
    pub absorption: usize,
    /// Emission samples set to zero.
    pub emission: usize,
}

/// Prunes the samples of one axis. `direction[i]` is Σ g² and `projection[i]` is Σ M·g
/// over sample i's fitted cells, g the model's cells per unit of the sample: the signed
/// estimate of sample i in its own σ is z_i = projection / (σ·√direction). Runs of
/// neighbouring samples with z_i < [`PRUNE_SIGNIFICANCE`] whose mean is no more
/// significant together (Σz/√n < [`PRUNE_SIGNIFICANCE`]) are set to zero; a weak tail
/// that is consistently positive over many samples stays. Samples on the short side of
/// the strongest are tested only with `both_sides`.
fn prune_axis(
    values: &mut [f64],
    direction: &[f64],
    projection: &[f64],
    sigma: f64,
    both_sides: bool,
) -> usize {
    // With `both_sides` false, only the long-wavelength side of the strongest sample: the
    // emission's blue side is shared between rows a rank-1 model cannot tell apart (the
    // UV-excited rows of HERPICER hold blue emission its other rows do not; pruning it
    // moved HERPICER under UV from ΔE2000 4.47 to 4.72).
    let Some(strongest) = values
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)
    else {
        return 0;
    };
    let z: Vec<f64> = direction
        .iter()
        .zip(projection)
        .map(|(d, p)| {
            if *d > 0.0 {
                p / (sigma * d.sqrt())
            } else {
                0.0
            }
        })
        .collect();
    let mut count = 0;
    let mut i = if both_sides { 0 } else { strongest + 1 };
    while i < z.len() {
        if z[i] >= PRUNE_SIGNIFICANCE {
            i += 1;
            continue;
        }
        let start = i;
        while i < z.len() && z[i] < PRUNE_SIGNIFICANCE {
            i += 1;
        }
        let run = &z[start..i];
        let together = run.iter().sum::<f64>() / (run.len() as f64).sqrt();
        if together < PRUNE_SIGNIFICANCE {
            for v in &mut values[start..i] {
                if *v > 0.0 {
                    *v = 0.0;
                    count += 1;
                }
            }
        }
    }
    count
}

/// Sets to zero the absorption (emission) samples of `sp` the data do not support: runs
/// of rows (of columns past the emission's peak) whose signed least-squares estimates
/// from their fitted cells in `data` are below [`PRUNE_SIGNIFICANCE`] of their noise
/// (`sigma` per cell), one by one and together. The cells the other samples make keep
/// their values. Returns the counts; nothing is pruned when `sigma` is not a positive
/// number or every sample would go.
pub fn prune_insignificant(
    objective: &Objective<'_>,
    data: &FitData,
    sp: &mut GridSpectra,
    sigma: f64,
) -> Pruned {
    if !(sigma.is_finite() && sigma > 0.0) {
        return Pruned::default();
    }
    let derived = objective.derived(sp);
    let (n_ex, n_em) = (sp.absorption.len(), sp.emission.len());
    let (mut row_dir, mut row_proj) = (vec![0.0f64; n_ex], vec![0.0f64; n_ex]);
    let (mut col_dir, mut col_proj) = (vec![0.0f64; n_em], vec![0.0f64; n_em]);
    for c in &data.off_diagonal {
        // The model's cell per unit absorption of its row, and per unit emission of its
        // column.
        let per_row = derived.scale * objective.row_factor(c.row) * sp.emission[c.column];
        let per_column = derived.scale * objective.row_factor(c.row) * sp.absorption[c.row];
        row_dir[c.row] += per_row * per_row;
        row_proj[c.row] += per_row * c.value;
        col_dir[c.column] += per_column * per_column;
        col_proj[c.column] += per_column * c.value;
    }
    let mut pruned_sp = sp.clone();
    let pruned = Pruned {
        absorption: prune_axis(&mut pruned_sp.absorption, &row_dir, &row_proj, sigma, true),
        emission: prune_axis(&mut pruned_sp.emission, &col_dir, &col_proj, sigma, false),
    };
    let empty = |v: &[f64]| v.iter().all(|x| *x <= 0.0);
    if pruned == Pruned::default() || empty(&pruned_sp.absorption) || empty(&pruned_sp.emission) {
        return Pruned::default();
    }
    // The cells keep their values: κ follows the emission normaliser and the photon
    // factor, which pruning moves, so that the product's scale s = κ/(κ/s) stays.
    let after = objective.derived(&pruned_sp);
    if after.kappa_per_scale > 0.0 {
        pruned_sp.kappa = (derived.scale * after.kappa_per_scale).clamp(0.0, 1.0);
    }
    *sp = pruned_sp;
    pruned
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run of samples whose estimates are noise (z < 2 one by one and together) goes to
    /// zero; a weak tail that is positive over many samples (each below 2σ, together far
    /// above) stays; samples above 2σ stay.
    #[test]
    fn runs_below_two_sigma_are_pruned_and_consistent_tails_stay() {
        let sigma = 1.0;
        // direction 1 per sample: z = projection / σ.
        let direction = vec![1.0; 12];
        // Strongest at 0; samples 1–3 noise (z 0.5, −0.3, 1.2: together 0.81); 4 strong
        // (z 5); 5–11 a tail at z 1.5 each (together 1.5·√7 = 3.97).
        let projection = [10.0, 0.5, -0.3, 1.2, 5.0, 1.5, 1.5, 1.5, 1.5, 1.5, 1.5, 1.5];
        let mut values = vec![1.0, 0.1, 0.05, 0.2, 0.5, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1];
        let count = prune_axis(&mut values, &direction, &projection, sigma, true);
        assert_eq!(count, 3);
        assert_eq!(&values[1..4], &[0.0, 0.0, 0.0]);
        assert_eq!(values[0], 1.0);
        assert_eq!(values[4], 0.5);
        assert!(values[5..].iter().all(|v| *v == 0.1));
    }

    /// With `both_sides` false only the samples past the strongest are tested (the
    /// emission's blue side, shared between rows a rank-1 model cannot tell apart, stays).
    #[test]
    fn one_sided_pruning_keeps_the_short_side() {
        let direction = vec![1.0; 5];
        let projection = [0.1, 0.2, 9.0, 0.1, 0.2];
        let mut values = vec![0.3, 0.3, 1.0, 0.3, 0.3];
        let count = prune_axis(&mut values, &direction, &projection, 1.0, false);
        assert_eq!(count, 2);
        assert_eq!(values, vec![0.3, 0.3, 1.0, 0.0, 0.0]);
    }
}
