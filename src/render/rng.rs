//! The random numbers of a path: PCG32 (O'Neill 2014), seeded per pixel so that a render
//! is the same whichever thread draws which pixel.

/// A PCG32 generator (XSH-RR output, 64-bit state).
#[derive(Debug, Clone)]
pub struct Rng {
    state: u64,
    increment: u64,
}

const MULTIPLIER: u64 = 6364136223846793005;

/// SplitMix64 finaliser: spreads neighbouring seeds over the whole state space.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator for stream `stream` of seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Rng {
        let mut rng = Rng {
            state: 0,
            increment: (mix(stream ^ 0x5851_F42D_4C95_7F2D) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(mix(seed));
        rng.next_u32();
        rng
    }

    /// The generator of pixel (x, y) of a render with `seed`; `pass` separates
    /// independent passes over the same pixel.
    pub fn for_pixel(seed: u64, x: u32, y: u32, pass: u32) -> Rng {
        let pixel = ((y as u64) << 32) | x as u64;
        Rng::new(mix(seed ^ mix(pass as u64)), pixel)
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.increment);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_reproducible() {
        let mut a = Rng::for_pixel(7, 3, 4, 0);
        let mut b = Rng::for_pixel(7, 3, 4, 0);
        let mut c = Rng::for_pixel(7, 4, 3, 0);
        let n = 100_000;
        let mut sum = 0.0;
        let mut same_as_c = 0;
        for _ in 0..n {
            let x = a.next_f32();
            assert_eq!(x, b.next_f32());
            assert!((0.0..1.0).contains(&x));
            if x == c.next_f32() {
                same_as_c += 1;
            }
            sum += x as f64;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.005);
        assert!(same_as_c < 10);
    }
}
