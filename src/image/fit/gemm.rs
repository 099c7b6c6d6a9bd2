//! Matrix products of the passes over an image, on strided views of a block's planes
//! (matrixmultiply's SGEMM, which picks the CPU's vector instructions at run time): a
//! block's cells are a pixels × cells matrix whose transpose costs nothing to view.

/// A read-only strided view of an f32 matrix.
#[derive(Debug, Clone, Copy)]
pub struct View<'a> {
    /// The storage.
    pub data: &'a [f32],
    /// Rows.
    pub rows: usize,
    /// Columns.
    pub cols: usize,
    /// Step between rows.
    pub row_stride: usize,
    /// Step between columns.
    pub col_stride: usize,
}

impl<'a> View<'a> {
    /// A row-major matrix.
    pub fn row_major(data: &'a [f32], rows: usize, cols: usize) -> View<'a> {
        View {
            data,
            rows,
            cols,
            row_stride: cols,
            col_stride: 1,
        }
    }

    /// A column-major matrix.
    pub fn column_major(data: &'a [f32], rows: usize, cols: usize) -> View<'a> {
        View {
            data,
            rows,
            cols,
            row_stride: 1,
            col_stride: rows,
        }
    }

    /// The transpose (same storage).
    pub fn t(self) -> View<'a> {
        View {
            data: self.data,
            rows: self.cols,
            cols: self.rows,
            row_stride: self.col_stride,
            col_stride: self.row_stride,
        }
    }

    /// Whether every element lies inside the storage.
    fn fits(&self) -> bool {
        self.rows == 0
            || self.cols == 0
            || (self.rows - 1) * self.row_stride + (self.cols - 1) * self.col_stride
                < self.data.len()
    }
}

/// a · b, row-major (a.rows × b.cols).
pub fn multiply(a: View<'_>, b: View<'_>) -> Vec<f32> {
    assert!(a.cols == b.rows, "inner dimensions differ");
    assert!(a.fits() && b.fits(), "a view reaches past its storage");
    let mut c = vec![0f32; a.rows * b.cols];
    if a.rows == 0 || b.cols == 0 || a.cols == 0 {
        return c;
    }
    // SAFETY: the dimensions and strides were checked against the slices above, so
    // every element matrixmultiply reads lies in `a.data` and `b.data`, and every one it
    // writes in `c` (row-major, a.rows × b.cols); the slices outlive the call.
    unsafe {
        matrixmultiply::sgemm(
            a.rows,
            a.cols,
            b.cols,
            1.0,
            a.data.as_ptr(),
            a.row_stride as isize,
            a.col_stride as isize,
            b.data.as_ptr(),
            b.row_stride as isize,
            b.col_stride as isize,
            0.0,
            c.as_mut_ptr(),
            b.cols as isize,
            1,
        );
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_of_strided_views_match_the_definition() {
        let a: Vec<f32> = (0..12).map(|v| v as f32 - 5.0).collect();
        let b: Vec<f32> = (0..8).map(|v| (v * v) as f32 * 0.5).collect();
        // a as 4 × 3 column-major, its transpose 3 × 4 times b as 4 × 2 row-major.
        let av = View::column_major(&a, 4, 3);
        let bv = View::row_major(&b, 4, 2);
        let c = multiply(av.t(), bv);
        for i in 0..3 {
            for j in 0..2 {
                let expected: f32 = (0..4).map(|k| a[i * 4 + k] * b[k * 2 + j]).sum();
                assert!((c[i * 2 + j] - expected).abs() < 1e-4);
            }
        }
    }
}
