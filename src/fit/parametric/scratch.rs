//! What an evaluation of the objective works in, kept per thread from one evaluation to
//! the next. Allocating and freeing its buffers (the grid model's, the matrix, the
//! adjoints: about fifty per evaluation) took about 8 % of a noise-aware search (perf,
//! HERPICER). Every buffer is cleared or zeroed before it is written, so an evaluation's
//! bits do not depend on what the buffers held.

use std::cell::Cell;

use super::{GridModel, Projection};

/// The buffers of one evaluation of [`super::Problem::cost_gradient`].
#[derive(Debug, Default)]
pub(super) struct Workspace {
    /// The model's grid quantities.
    pub model: GridModel,
    /// e_jk·u_j per component.
    pub weighted_emission: Vec<Vec<f64>>,
    /// The model matrix, then its residuals, then its adjoints.
    pub matrix: Vec<f64>,
    /// Per diagonal sample: its residual and how it was projected.
    pub diagonal: Vec<(f64, Option<Projection>)>,
    /// Per light and column: Σ_i L_i·r_ij.
    pub column_sum: Vec<f64>,
    /// Per light and Lab channel: the linearised colour difference.
    pub patch: Vec<f64>,
    /// Per row: Σ_j r_ij².
    pub row_square: Vec<f64>,
    /// Per light and column: the colour term's pull on reradiated and diagonal residuals.
    pub q: Vec<f64>,
    pub h: Vec<f64>,
    /// The adjoints of the scales, absorptions, emissions, κ, mean emission wavelengths
    /// and reflectances.
    pub scale_bar: Vec<f64>,
    pub a_bar: Vec<Vec<f64>>,
    pub e_bar: Vec<Vec<f64>>,
    pub kappa_bar: Vec<f64>,
    pub mean_bar: Vec<f64>,
    pub r_bar: Vec<f64>,
    /// A row's light weights.
    pub light_weights: Vec<f64>,
    /// Σ_i F̄_ij·a_ik·x_ik for one component.
    pub column_adjoint: Vec<f64>,
    /// Σ_j F̄_ij·e_jk·u_j for one component.
    pub row_dot: Vec<f64>,
    /// The adjoint of one component's unnormalised absorption.
    pub g_bar: Vec<f64>,
}

thread_local! {
    static KEPT: Cell<Option<Box<Workspace>>> = const { Cell::new(None) };
}

/// This thread's workspace, or a new one (the first evaluation on a thread, or one whose
/// thread's workspace is lent out).
pub(super) fn take() -> Box<Workspace> {
    KEPT.try_with(Cell::take).ok().flatten().unwrap_or_default()
}

/// Keeps `workspace` for this thread's next evaluation.
pub(super) fn give_back(workspace: Box<Workspace>) {
    let _ = KEPT.try_with(|kept| kept.set(Some(workspace)));
}

/// `buffer` as `n` zeros.
pub(super) fn zeroed(buffer: &mut Vec<f64>, n: usize) {
    buffer.clear();
    buffer.resize(n, 0.0);
}

/// `rows` as `count` rows of `n` zeros each.
pub(super) fn zeroed_rows(rows: &mut Vec<Vec<f64>>, count: usize, n: usize) {
    rows.resize_with(count, Vec::new);
    for row in rows.iter_mut() {
        zeroed(row, n);
    }
}
