//! The solvers of the seams' least squares ([`super::solve`]): conjugate
//! gradients to a tolerance, and a fixed number of Chebyshev steps whose
//! solution at a texel reads only the texels within a few rows of it.
//!
//! In: a symmetric positive definite operator (its product with a block of
//! vectors), its diagonal, the right-hand sides and a start, several
//! channels at once. Out: the solution (conjugate gradients: and the
//! iterations the slowest channel took, whether every channel reached its
//! tolerance).

use super::super::filter::Filter;

/// The Chebyshev steps of a bilinear page's solve ([`Solver::Steps`]).
/// Fewer leave more of the seams and the border fit's gaps open, more
/// widen what a texel reads (`docs/measurements/constants.md`, STEPS).
pub const STEPS: usize = 60;

/// The low end of the spectrum the Chebyshev steps are tuned to (of D^-1
/// M, whose high end is at most a row's tap count): error components
/// above it shrink at conjugate gradients' worst-case rate, those below
/// more slowly (`docs/measurements/constants.md`, STEPS).
pub const SPECTRUM_LOW: f64 = 0.02;

/// How a [`System`](super::solve::System) is solved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Solver {
    /// Conjugate gradients to their tolerance: a solved value reads its
    /// whole component.
    Converged,
    /// [`STEPS`] Chebyshev steps for D^-1 M's spectrum within
    /// [[`SPECTRUM_LOW`], `high`]: a solved value reads only the unknowns
    /// within `STEPS` + 1 rows of it. `high` must bound the spectrum: a
    /// row's taps (x^T M x <= taps x^T D x by Cauchy-Schwarz).
    Steps { high: f64 },
}

impl Solver {
    /// A page's stitch through `filter`: bilinear rows hold 8 taps at most
    /// (two cells); bicubic pages free every texel a lookup reads and are
    /// baked whole by a rebake, so they keep conjugate gradients.
    pub fn for_filter(filter: Filter) -> Solver {
        match filter {
            Filter::Bilinear => Solver::Steps { high: 8.0 },
            Filter::Bicubic => Solver::Converged,
        }
    }

    /// The rows a solved value reads beyond its own (`None`: its whole
    /// component).
    pub fn reach(self) -> Option<usize> {
        match self {
            Solver::Converged => None,
            Solver::Steps { .. } => Some(STEPS + 1),
        }
    }
}

/// One constraint: unknowns and weights (side A positive, side B
/// negative), duplicates merged; and the fixed texels it reads, with
/// theirs.
#[derive(Default)]
pub(super) struct Row {
    pub(super) free: Vec<(u32, f64)>,
    pub(super) fixed: Vec<(u32, f64)>,
    /// For a one-sided constraint: the [`Anchor`](super::Anchor) its lookup must meet.
    pub(super) anchor: Option<usize>,
    /// The row's scale (its weight: the anchor's, or 1).
    pub(super) scale: f64,
}

/// Relative residual at which conjugate gradients stop.
const TOLERANCE: f64 = 1e-5;

/// Most iterations per component and channel.
const MAX_ITERATIONS: usize = 2000;

/// Solves M X = B for symmetric positive definite M and `channels`
/// right-hand sides at once (`b`, `x`: row-major, `channels` per unknown;
/// `apply(x, y)`: Y = M X for all channels), Jacobi-preconditioned by
/// `diagonal`, from `start` (the baked values). Each channel has its own
/// step lengths and stops at [`TOLERANCE`] of its right-hand side. Returns
/// X, the iterations the slowest channel took and whether every channel
/// converged.
pub(crate) fn conjugate_gradients(
    apply: &impl Fn(&[f64], &mut [f64]),
    diagonal: &[f64],
    b: &[f64],
    start: &[f64],
    channels: usize,
) -> (Vec<f64>, usize, bool) {
    let n = diagonal.len();
    let c = channels;
    let dot = |u: &[f64], v: &[f64], k: usize| -> f64 {
        (0..n).map(|i| u[i * c + k] * v[i * c + k]).sum()
    };
    // Relative to the right-hand side, with an absolute floor of 1e-6 RMS
    // per unknown (a channel that is ~0 everywhere).
    let floor = 1e-6 / TOLERANCE * (n as f64).sqrt();
    let norm_b: Vec<f64> = (0..c).map(|k| dot(b, b, k).sqrt().max(floor)).collect();
    let mut x = start.to_vec();
    let mut ax = vec![0.0; n * c];
    apply(&x, &mut ax);
    let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut z: Vec<f64> = (0..n * c).map(|j| r[j] / diagonal[j / c]).collect();
    let mut p = z.clone();
    let mut rz: Vec<f64> = (0..c).map(|k| dot(&r, &z, k)).collect();
    let mut done = vec![false; c];
    let mut ap = vec![0.0; n * c];
    for iteration in 0..MAX_ITERATIONS {
        for k in 0..c {
            let norm_r = dot(&r, &r, k).sqrt();
            if !norm_r.is_finite() {
                return (start.to_vec(), iteration, false);
            }
            done[k] |= norm_r <= TOLERANCE * norm_b[k];
        }
        if done.iter().all(|&d| d) {
            return (x, iteration, true);
        }
        apply(&p, &mut ap);
        for k in 0..c {
            if done[k] {
                continue;
            }
            let pap = dot(&p, &ap, k);
            if pap <= 0.0 {
                done[k] = true;
                continue;
            }
            let alpha = rz[k] / pap;
            for i in 0..n {
                x[i * c + k] += alpha * p[i * c + k];
                r[i * c + k] -= alpha * ap[i * c + k];
                z[i * c + k] = r[i * c + k] / diagonal[i];
            }
            let rz_next = dot(&r, &z, k);
            let beta = rz_next / rz[k];
            rz[k] = rz_next;
            for i in 0..n {
                p[i * c + k] = z[i * c + k] + beta * p[i * c + k];
            }
        }
    }
    let converged = (0..c).all(|k| dot(&r, &r, k).sqrt() <= TOLERANCE * norm_b[k]);
    (x, MAX_ITERATIONS, converged)
}

/// Solves M X = B as [`conjugate_gradients`] does, by `iterations` steps
/// of Chebyshev semi-iteration (Saad, "Iterative Methods for Sparse Linear
/// Systems", 2nd ed., Algorithm 12.1), Jacobi-preconditioned by
/// `diagonal`, whose spectrum D^-1 M is taken to lie in `[low, high]`.
/// Its steps are fixed numbers (no inner product), so a step moves each
/// unknown by what M's rows tie it to: after k steps an unknown has read
/// only the unknowns within k + 1 rows of it (the start's residual reads
/// one), and a value not known (NaN) reaches exactly those. Error
/// components with eigenvalues in `[low, high]` shrink like Chebyshev
/// polynomials (the rate conjugate gradients guarantee), those below
/// `low` more slowly, and none grows provided `high` bounds the spectrum.
/// Returns X.
pub(crate) fn chebyshev(
    apply: &impl Fn(&[f64], &mut [f64]),
    diagonal: &[f64],
    b: &[f64],
    start: &[f64],
    channels: usize,
    (low, high): (f64, f64),
    iterations: usize,
) -> Vec<f64> {
    let c = channels;
    let (theta, delta) = ((high + low) / 2.0, (high - low) / 2.0);
    let sigma = theta / delta;
    let mut x = start.to_vec();
    let mut r = vec![0.0; x.len()];
    apply(&x, &mut r);
    r.iter_mut().zip(b).for_each(|(r, b)| *r = b - *r);
    let mut d: Vec<f64> = (r.iter().enumerate())
        .map(|(j, r)| r / diagonal[j / c] / theta)
        .collect();
    let mut rho = 1.0 / sigma;
    let mut md = vec![0.0; x.len()];
    for step in 0..iterations {
        x.iter_mut().zip(&d).for_each(|(x, d)| *x += d);
        if step + 1 == iterations {
            break;
        }
        apply(&d, &mut md);
        let next = 1.0 / (2.0 * sigma - rho);
        for j in 0..x.len() {
            r[j] -= md[j];
            d[j] = next * rho * d[j] + 2.0 * next / delta * r[j] / diagonal[j / c];
        }
        rho = next;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conjugate_gradients_solve_a_small_spd_system() {
        // M = [[4, 1], [1, 3]], b = [1, 2]: x = [1/11, 7/11].
        let apply = |x: &[f64], y: &mut [f64]| {
            y[0] = 4.0 * x[0] + x[1];
            y[1] = x[0] + 3.0 * x[1];
        };
        let (x, _, ok) = conjugate_gradients(&apply, &[4.0, 3.0], &[1.0, 2.0], &[1.0, 2.0], 1);
        assert!(ok);
        assert!((x[0] - 1.0 / 11.0).abs() < 1e-9 && (x[1] - 7.0 / 11.0).abs() < 1e-9);
    }

    #[test]
    fn chebyshev_steps_solve_a_chain_and_read_only_their_reach() {
        // A chain of n unknowns, each tied to its neighbours by a row of
        // weight s (x_i - x_i+1 = 0) and to its data term: M = I + s^2 L,
        // whose Jacobi-preconditioned spectrum lies in (0, 2).
        let (n, s2) = (200usize, 4.0f64);
        let apply = |x: &[f64], y: &mut [f64]| {
            for i in 0..n {
                let mut v = x[i];
                if i > 0 {
                    v += s2 * (x[i] - x[i - 1]);
                }
                if i + 1 < n {
                    v += s2 * (x[i] - x[i + 1]);
                }
                y[i] = v;
            }
        };
        let diagonal: Vec<f64> = (0..n)
            .map(|i| 1.0 + s2 * ((i > 0) as u8 + (i + 1 < n) as u8) as f64)
            .collect();
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 11) as f64 / 11.0).collect();
        // The exact solution, by the tridiagonal (Thomas) elimination.
        let (mut c, mut d) = (vec![0.0; n], vec![0.0; n]);
        for i in 0..n {
            let (lower, upper) = (if i > 0 { -s2 } else { 0.0 }, -s2);
            let m = diagonal[i] - lower * if i > 0 { c[i - 1] } else { 0.0 };
            c[i] = upper / m;
            d[i] = (b[i] - lower * if i > 0 { d[i - 1] } else { 0.0 }) / m;
        }
        let mut exact = vec![0.0; n];
        for i in (0..n).rev() {
            exact[i] = d[i] - if i + 1 < n { c[i] * exact[i + 1] } else { 0.0 };
        }
        let x = chebyshev(&apply, &diagonal, &b, &b, 1, (SPECTRUM_LOW, 2.0), STEPS);
        let mut mx = vec![0.0; n];
        apply(&x, &mut mx);
        let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|v| v * v).sum::<f64>().sqrt();
        let residual = norm(&mut (0..n).map(|i| b[i] - mx[i])) / norm(&mut b.iter().copied());
        let error = (0..n).map(|i| (x[i] - exact[i]).abs()).fold(0.0, f64::max);
        assert!(error < 1e-3 && residual < 1e-2, "{error} {residual}");
        // A value not known at one end reaches STEPS unknowns and no more;
        // the others are the same to the bit.
        let mut start = b.clone();
        start[0] = f64::NAN;
        let y = chebyshev(&apply, &diagonal, &b, &start, 1, (SPECTRUM_LOW, 2.0), STEPS);
        let reached = y.iter().take_while(|v| v.is_nan()).count();
        assert!((STEPS / 2..=STEPS + 1).contains(&reached), "{reached}");
        assert!(
            y[reached..]
                .iter()
                .zip(&x[reached..])
                .all(|(a, b)| a.to_bits() == b.to_bits())
        );
    }
}
