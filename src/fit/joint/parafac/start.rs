//! The closed-form start of the PARAFAC iterations: the leading singular vectors of the
//! excitation and emission unfoldings (a sequentially truncated HOSVD), each made
//! non-negative as NNDSVD does, scores 1.

use super::{Factors, START_FLOOR, Work};

/// The closed-form start (see the module doc).
pub(super) fn start(work: &Work<'_>, k: usize) -> Factors {
    let t = work.t;
    let (s_n, n_ex, n_em) = (t.samples, t.n_ex, t.n_em);
    let x = &work.filled;
    // Excitation mode: the n_ex × n_ex Gram of the excitation unfolding.
    let mut gram = nalgebra::DMatrix::<f64>::zeros(n_ex, n_ex);
    for s in 0..s_n {
        for a in 0..n_ex {
            let ra = &x[t.index(s, a, 0)..t.index(s, a, 0) + n_em];
            for b in a..n_ex {
                let rb = &x[t.index(s, b, 0)..t.index(s, b, 0) + n_em];
                gram[(a, b)] += crate::numeric::dot(ra, rb);
            }
        }
    }
    for a in 0..n_ex {
        for b in 0..a {
            gram[(a, b)] = gram[(b, a)];
        }
    }
    let ex_vectors = leading_eigenvectors(gram, k);
    // Emission mode from the excitation-projected data (n_em × s·k), through the small
    // Gram of its columns.
    let kx = ex_vectors.len();
    let columns = s_n * kx;
    let mut projected = vec![0.0; columns * n_em];
    for s in 0..s_n {
        for (c, v) in ex_vectors.iter().enumerate() {
            let out = &mut projected[(s * kx + c) * n_em..(s * kx + c + 1) * n_em];
            for (ex, w) in v.iter().enumerate() {
                let row = &x[t.index(s, ex, 0)..t.index(s, ex, 0) + n_em];
                for (o, r) in out.iter_mut().zip(row) {
                    *o += w * r;
                }
            }
        }
    }
    let mut small = nalgebra::DMatrix::<f64>::zeros(columns, columns);
    for a in 0..columns {
        for b in a..columns {
            let d = crate::numeric::dot(
                &projected[a * n_em..(a + 1) * n_em],
                &projected[b * n_em..(b + 1) * n_em],
            );
            small[(a, b)] = d;
            small[(b, a)] = d;
        }
    }
    let em_vectors: Vec<Vec<f64>> = leading_eigenvectors(small, k)
        .into_iter()
        .map(|v| {
            let mut u = vec![0.0; n_em];
            for (c, w) in v.iter().enumerate() {
                for (o, p) in u.iter_mut().zip(&projected[c * n_em..(c + 1) * n_em]) {
                    *o += w * p;
                }
            }
            u
        })
        .collect();
    Factors {
        k,
        scores: vec![1.0; s_n * k],
        excitation: non_negative_parts(&ex_vectors, k, n_ex),
        emission: non_negative_parts(&em_vectors, k, n_em),
    }
}

/// The eigenvectors of the `k` largest eigenvalues of a symmetric matrix, largest first
/// (fewer when the matrix is smaller).
fn leading_eigenvectors(m: nalgebra::DMatrix<f64>, k: usize) -> Vec<Vec<f64>> {
    let n = m.nrows();
    let eigen = m.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    order
        .into_iter()
        .take(k)
        .map(|c| eigen.eigenvectors.column(c).iter().copied().collect())
        .collect()
}

/// NNDSVD's rule per vector: the larger (in norm) of its positive and negative parts,
/// scaled to max 1, plus [`START_FLOOR`]; missing vectors (a mode shorter than k) are flat.
fn non_negative_parts(vectors: &[Vec<f64>], k: usize, n: usize) -> Vec<f64> {
    let mut out = Vec::with_capacity(k * n);
    for c in 0..k {
        let part: Vec<f64> = match vectors.get(c) {
            Some(v) => {
                let positive: f64 = v.iter().map(|x| x.max(0.0).powi(2)).sum();
                let negative: f64 = v.iter().map(|x| (-x).max(0.0).powi(2)).sum();
                let sign = if positive >= negative { 1.0 } else { -1.0 };
                v.iter().map(|x| (sign * x).max(0.0)).collect()
            }
            None => vec![1.0; n],
        };
        let peak = part.iter().cloned().fold(0.0, f64::max);
        out.extend(
            part.iter()
                .map(|x| if peak > 0.0 { x / peak } else { 1.0 } + START_FLOOR),
        );
    }
    out
}
