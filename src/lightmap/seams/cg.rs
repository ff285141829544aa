//! Conjugate gradients for the seams' least squares ([`super::solve`]).
//!
//! In: a symmetric positive definite operator (its product with a block of
//! vectors), its diagonal, the right-hand sides and a start, several
//! channels at once. Out: the solution, the iterations the slowest channel
//! took and whether every channel reached [`TOLERANCE`].

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
}
