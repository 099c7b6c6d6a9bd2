//! A quantile sketch of non-negative values (each pixel's ΔE2000 under a light).
//!
//! The judge of every K reports the median, the 99th percentile and the largest ΔE2000
//! of an image's pixels. Gathering every pixel's value to sort them costs memory (and, on
//! a cluster, transfer) that grows with the image: 16.7 M pixels × 4 lights is 0.5 GB
//! as f64. A sketch counts the values per bucket instead: a bucket is the value's f32
//! bit pattern without its lowest [`DROPPED_BITS`] bits, so its width is 2⁻¹⁰ of the
//! value (10 of the mantissa's 23 bits kept), and the buckets an image fills are bounded
//! by the range of its values (1,024 per octave), not by its pixels. Counts add exactly,
//! so sketches merge in any grouping and order with the same result: however the pixels
//! were split into chunks, threads or workers.

use serde::{Deserialize, Serialize};

/// Low bits of an f32 a bucket ignores: buckets 2⁻¹⁰ of their value wide.
pub const DROPPED_BITS: u32 = 13;

/// Counts of non-negative values per bucket, and their largest value.
///
/// A quantile read from it is [`crate::numeric::quantile`]'s linear interpolation
/// between the two order statistics around the rank, each taken as the middle of its
/// bucket: within 2⁻¹¹ (0.05 %) of the larger of the two of the exact quantile. The largest (q = 1) is
/// exact. Values that are not finite are left out, as `numeric::quantile` leaves them.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct QuantileSketch {
    /// (bucket, count), by increasing bucket, every count positive.
    buckets: Vec<(u32, u64)>,
    /// The largest value counted.
    max: Option<f32>,
}

fn bucket_of(value: f32) -> u32 {
    // Non-negative finite f32s order as their bit patterns do; -0.0 and any negative
    // value (none arise from a ΔE) count as 0.
    if value > 0.0 {
        value.to_bits() >> DROPPED_BITS
    } else {
        0
    }
}

/// The middle of a bucket's values.
fn middle(bucket: u32) -> f64 {
    let lower = f64::from(f32::from_bits(bucket << DROPPED_BITS));
    let upper = f64::from(f32::from_bits((bucket + 1) << DROPPED_BITS));
    if upper.is_finite() {
        0.5 * (lower + upper)
    } else {
        lower
    }
}

impl QuantileSketch {
    /// The sketch of `values`.
    pub fn of(values: impl IntoIterator<Item = f32>) -> QuantileSketch {
        let mut max: Option<f32> = None;
        let mut ids: Vec<u32> = values
            .into_iter()
            .filter(|v| v.is_finite())
            .map(|v| {
                let v = v.max(0.0);
                max = Some(max.map_or(v, |m| m.max(v)));
                bucket_of(v)
            })
            .collect();
        ids.sort_unstable();
        let mut buckets: Vec<(u32, u64)> = Vec::new();
        for id in ids {
            match buckets.last_mut() {
                Some((b, n)) if *b == id => *n += 1,
                _ => buckets.push((id, 1)),
            }
        }
        QuantileSketch { buckets, max }
    }

    /// Values counted.
    pub fn count(&self) -> u64 {
        self.buckets.iter().map(|&(_, n)| n).sum()
    }

    /// Buckets holding values (what the sketch costs to keep or send).
    pub fn buckets(&self) -> usize {
        self.buckets.len()
    }

    /// Adds `other`'s counts to these (exact: the result does not depend on the order
    /// in which sketches are merged).
    pub fn merge(&mut self, other: &QuantileSketch) {
        if other.buckets.is_empty() {
            return;
        }
        let mut merged = Vec::with_capacity(self.buckets.len() + other.buckets.len());
        let (mut a, mut b) = (
            self.buckets.iter().peekable(),
            other.buckets.iter().peekable(),
        );
        loop {
            let next = match (a.peek(), b.peek()) {
                (Some(&&(x, n)), Some(&&(y, m))) => {
                    if x == y {
                        a.next();
                        b.next();
                        (x, n + m)
                    } else if x < y {
                        a.next();
                        (x, n)
                    } else {
                        b.next();
                        (y, m)
                    }
                }
                (Some(&&p), None) => {
                    a.next();
                    p
                }
                (None, Some(&&p)) => {
                    b.next();
                    p
                }
                (None, None) => break,
            };
            merged.push(next);
        }
        self.buckets = merged;
        self.max = match (self.max, other.max) {
            (Some(x), Some(y)) => Some(x.max(y)),
            (x, y) => x.or(y),
        };
    }

    /// The `q`-quantile (0 ≤ q ≤ 1) of the values counted; NaN when none were.
    pub fn quantile(&self, q: f64) -> f64 {
        let count = self.count();
        let Some(max) = self.max else {
            return f64::NAN;
        };
        if count == 0 {
            return f64::NAN;
        }
        let max = f64::from(max);
        let pos = q.clamp(0.0, 1.0) * (count - 1) as f64;
        if pos >= (count - 1) as f64 {
            return max;
        }
        let (lo, hi) = (pos.floor() as u64, pos.ceil() as u64);
        let at = |rank: u64| -> f64 {
            let mut seen = 0u64;
            for &(bucket, n) in &self.buckets {
                seen += n;
                if rank < seen {
                    return middle(bucket).min(max);
                }
            }
            max
        };
        let (low, high) = (at(lo), at(hi));
        low + (high - low) * (pos - lo as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::quantile;

    /// Values spread over five decades, with ties and zeros, as ΔE2000s are.
    fn values(n: usize, seed: u64) -> Vec<f32> {
        let mut state = seed;
        (0..n)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = (state >> 11) as f64 / (1u64 << 53) as f64;
                match i % 97 {
                    0 => 0.0,
                    1 => 0.5,
                    _ => (10f64.powf(5.0 * u - 3.0)) as f32,
                }
            })
            .collect()
    }

    #[test]
    fn quantiles_are_within_the_bucket_precision_of_the_exact_ones() {
        for n in [1usize, 2, 3, 10, 1000, 54_321] {
            let v = values(n, n as u64);
            let exact: Vec<f64> = v.iter().map(|&x| f64::from(x)).collect();
            let mut sorted = exact.clone();
            sorted.sort_by(f64::total_cmp);
            let sketch = QuantileSketch::of(v.iter().copied());
            assert_eq!(sketch.count(), n as u64);
            for q in [0.0, 0.01, 0.25, 0.5, 0.9, 0.99, 0.999, 1.0] {
                let (want, got) = (quantile(&exact, q), sketch.quantile(q));
                // Half a bucket of the larger order statistic around the rank.
                let larger = sorted[(q * (n - 1) as f64).ceil() as usize];
                let tolerance = larger * 2f64.powi(-11) * 1.0001 + 1e-30;
                assert!(
                    (want - got).abs() <= tolerance,
                    "n {n} q {q}: exact {want}, sketch {got}"
                );
            }
            assert_eq!(
                sketch.quantile(1.0),
                quantile(&exact, 1.0),
                "the largest is exact"
            );
        }
    }

    #[test]
    fn merging_in_any_grouping_gives_the_same_sketch() {
        let v = values(20_000, 7);
        let whole = QuantileSketch::of(v.iter().copied());
        for chunk in [1usize, 7, 4096, 20_000] {
            let mut forward = QuantileSketch::default();
            for part in v.chunks(chunk) {
                forward.merge(&QuantileSketch::of(part.iter().copied()));
            }
            let mut backward = QuantileSketch::default();
            for part in v.chunks(chunk).rev() {
                backward.merge(&QuantileSketch::of(part.iter().copied()));
            }
            assert_eq!(forward, whole, "chunks of {chunk}");
            assert_eq!(backward, whole, "chunks of {chunk}, reversed");
        }
        // Bounded by the values' range: at most 1,024 buckets per octave.
        let octaves = (f64::from(*v.iter().max_by(|a, b| a.total_cmp(b)).unwrap()) / 1e-3)
            .log2()
            .ceil() as usize;
        assert!(
            whole.buckets() <= 1024 * (octaves + 1) + 1,
            "{}",
            whole.buckets()
        );
    }

    #[test]
    fn empty_and_non_finite() {
        let empty = QuantileSketch::of(std::iter::empty());
        assert!(empty.quantile(0.5).is_nan());
        let some = QuantileSketch::of([f32::NAN, 2.0, f32::INFINITY, 1.0]);
        assert_eq!(some.count(), 2);
        assert_eq!(some.quantile(1.0), 2.0);
        let mut merged = QuantileSketch::default();
        merged.merge(&empty);
        merged.merge(&some);
        assert_eq!(merged, some);
    }
}
