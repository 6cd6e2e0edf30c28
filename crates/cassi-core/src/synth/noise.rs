//! Band-limited value noise and fractal (fBm) sums, from lattice tables
//! filled by the project's [`Rng`]. Sampling is a pure function of the
//! position, so rows can be evaluated in parallel with identical results.

use crate::rng::Rng;

/// Side of each periodic lattice table (cells).
const TABLE: usize = 128;

/// One octave: a periodic `TABLE`×`TABLE` lattice of values in [−1, 1],
/// interpolated with a C² quintic fade, on cells `cell` pixels wide, with the
/// coordinates rotated so lattice axes do not line up with the pixel grid.
#[derive(Debug, Clone)]
struct Octave {
    values: Vec<f32>,
    inv_cell: f64,
    cos: f64,
    sin: f64,
    offset: (f64, f64),
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

impl Octave {
    fn new(rng: &mut Rng, cell: f64) -> Self {
        let values = (0..TABLE * TABLE)
            .map(|_| (2.0 * rng.uniform() - 1.0) as f32)
            .collect();
        let angle = rng.uniform_in(0.0, std::f64::consts::TAU);
        Self {
            values,
            inv_cell: 1.0 / cell,
            cos: libm::cos(angle),
            sin: libm::sin(angle),
            offset: (
                rng.uniform_in(0.0, TABLE as f64),
                rng.uniform_in(0.0, TABLE as f64),
            ),
        }
    }

    fn sample(&self, x: f64, y: f64) -> f64 {
        let u = (self.cos * x - self.sin * y) * self.inv_cell + self.offset.0;
        let v = (self.sin * x + self.cos * y) * self.inv_cell + self.offset.1;
        let (fu, fv) = (u.floor(), v.floor());
        let (tu, tv) = (fade(u - fu), fade(v - fv));
        let n = TABLE as i64;
        let i0 = (fu as i64).rem_euclid(n) as usize;
        let j0 = (fv as i64).rem_euclid(n) as usize;
        let i1 = (i0 + 1) % TABLE;
        let j1 = (j0 + 1) % TABLE;
        let at = |i: usize, j: usize| f64::from(self.values[j * TABLE + i]);
        let a = at(i0, j0) + tu * (at(i1, j0) - at(i0, j0));
        let b = at(i0, j1) + tu * (at(i1, j1) - at(i0, j1));
        a + tv * (b - a)
    }
}

/// A fractal sum of value-noise octaves: cells `coarsest`, `coarsest/2`, …
/// down to about `finest` pixels, amplitudes falling by `gain` per octave.
/// Output roughly in [−1, 1] (normalised by the amplitude sum).
#[derive(Debug, Clone)]
pub struct Fbm {
    octaves: Vec<(Octave, f64)>,
}

impl Fbm {
    pub fn new(rng: &mut Rng, coarsest: f64, finest: f64, gain: f64) -> Self {
        let mut octaves = Vec::new();
        let mut cell = coarsest;
        let mut amp = 1.0;
        let mut total = 0.0;
        while cell >= finest * 0.999 || octaves.is_empty() {
            octaves.push((Octave::new(rng, cell), amp));
            total += amp;
            cell *= 0.5;
            amp *= gain;
        }
        for o in &mut octaves {
            o.1 /= total;
        }
        Self { octaves }
    }

    pub fn sample(&self, x: f64, y: f64) -> f64 {
        self.octaves.iter().map(|(o, a)| a * o.sample(x, y)).sum()
    }
}

/// Per-pixel i.i.d. grain in [−1, 1] (surface micro-texture / paper grain),
/// a periodic table indexed by integer pixel position.
#[derive(Debug, Clone)]
pub struct Grain {
    values: Vec<f32>,
}

const GRAIN: usize = 256;

impl Grain {
    pub fn new(rng: &mut Rng) -> Self {
        Self {
            values: (0..GRAIN * GRAIN)
                .map(|_| (2.0 * rng.uniform() - 1.0) as f32)
                .collect(),
        }
    }

    pub fn at(&self, row: usize, col: usize) -> f64 {
        // An odd-multiplier scramble of the row keeps the 256-periodicity from
        // lining up into visible repeats on large scenes.
        let r = (row.wrapping_mul(7) + col / GRAIN * 13) % GRAIN;
        f64::from(self.values[r * GRAIN + (col + row / GRAIN * 101) % GRAIN])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fbm_is_continuous_bounded_and_varies() {
        let f = Fbm::new(&mut Rng::new(1), 32.0, 2.0, 0.6);
        let mut prev = f.sample(0.0, 10.0);
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for i in 1..2000 {
            let x = i as f64 * 0.01;
            let v = f.sample(x, 10.0);
            assert!(v.abs() <= 1.0);
            // Step 0.01 px on 2-px cells: a C¹ interpolant moves little.
            assert!((v - prev).abs() < 0.02, "jump at {x}: {prev} → {v}");
            prev = v;
            lo = lo.min(v);
            hi = hi.max(v);
        }
        assert!(hi - lo > 0.2, "fBm nearly constant: {lo}..{hi}");
    }
}
