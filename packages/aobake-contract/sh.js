// The SH arithmetic both engine importers share (the packages aobake-three
// for three.js and aobake-babylon for Babylon.js): the contract's
// real SH basis, quadrature on the sphere, the triple product Gamma and the
// per-environment matrix P of the visibility layer. No engine import.
//
// In: directions (unit [x, y, z] in the bake's frame), functions of them,
// and an environment's 9 RGB radiance coefficients. Out: basis values,
// projections, Gamma_ijk and P_ik = sum_j Gamma_ijk L_j as a 16 x 16 RGBA
// float array (the layout both shaders read).

/** The 16 real SH basis functions (the contract's order and constants);
 * the first 9 are the lightmap's. */
export function basis16([x, y, z]) {
  return [
    0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x,
    1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
    1.092548 * x * z, 0.546274 * (x * x - y * y),
    0.590044 * y * (3 * x * x - y * y), 2.890611 * x * y * z,
    0.457046 * y * (5 * z * z - 1), 0.373176 * z * (5 * z * z - 3),
    0.457046 * x * (5 * z * z - 1), 1.445306 * z * (x * x - y * y),
    0.590044 * x * (x * x - 3 * y * y),
  ];
}

/** The 9 basis functions of the lightmap's c_i. */
export const basis9 = (w) => basis16(w).slice(0, 9);

let rule = null;
/** A product rule on the sphere: 16 Gauss-Legendre nodes in z (by Newton
 * on P_16) x 32 azimuths, exact for polynomials of degree 31 in z and 31
 * in azimuth (more than any product here needs). [direction, weight]. */
export function sphereRule() {
  if (rule) return rule;
  const n = 16;
  const az = 32;
  rule = [];
  for (let i = 0; i < n; i++) {
    let t = Math.cos((Math.PI * (i + 0.75)) / (n + 0.5));
    for (let it = 0; it < 100; it++) {
      let p0 = 1;
      let p1 = t;
      for (let k = 2; k <= n; k++) [p0, p1] = [p1, ((2 * k - 1) * t * p1 - (k - 1) * p0) / k];
      const dp = (n * (t * p1 - p0)) / (t * t - 1);
      const step = p1 / dp;
      t -= step;
      if (Math.abs(step) < 1e-15) {
        let q0 = 1;
        let q1 = t;
        for (let k = 2; k <= n; k++) [q0, q1] = [q1, ((2 * k - 1) * t * q1 - (k - 1) * q0) / k];
        const d = (n * (t * q1 - q0)) / (t * t - 1);
        const w = 2 / ((1 - t * t) * d * d);
        const r = Math.sqrt(Math.max(0, 1 - t * t));
        for (let a = 0; a < az; a++) {
          const phi = ((a + 0.5) / az) * 2 * Math.PI;
          rule.push([[r * Math.cos(phi), r * Math.sin(phi), t], (w * 2 * Math.PI) / az]);
        }
        break;
      }
    }
  }
  return rule;
}

/** Int f(w) Y_i(w) dw for the 9 basis functions, f returning [r, g, b]:
 * 9 x [r, g, b]. */
export function project(f) {
  const out = Array.from({ length: 9 }, () => [0, 0, 0]);
  for (const [dir, dw] of sphereRule()) {
    const y = basis9(dir);
    const v = f(dir);
    for (let k = 0; k < 9; k++) for (let c = 0; c < 3; c++) out[k][c] += dw * y[k] * v[c];
  }
  return out;
}

let gauntTable = null;
/** Gamma_ijk = Int Y_i Y_j Y_k dw (i, k < 16, j < 9), by sphereRule (exact
 * for these degrees). Flat: g[(i * 9 + j) * 16 + k]. */
export function gaunt() {
  if (gauntTable) return gauntTable;
  const g = new Float64Array(16 * 9 * 16);
  for (const [dir, w] of sphereRule()) {
    const y = basis16(dir);
    for (let i = 0; i < 16; i++) {
      for (let j = 0; j < 9; j++) {
        const yij = w * y[i] * y[j];
        for (let k = 0; k < 16; k++) g[(i * 9 + j) * 16 + k] += yij * y[k];
      }
    }
  }
  gauntTable = g;
  return g;
}

/** P_ik = sum_j Gamma_ijk L_j for the 9 RGB coefficients `l` (arrays of
 * 3): a 16 x 16 RGBA float array, row i, column k. */
export function radianceProduct(l) {
  const g = gaunt();
  const p = new Float32Array(16 * 16 * 4);
  for (let i = 0; i < 16; i++) {
    for (let k = 0; k < 16; k++) {
      for (let c = 0; c < 3; c++) {
        let sum = 0;
        for (let j = 0; j < 9; j++) sum += g[(i * 9 + j) * 16 + k] * l[j][c];
        p[(i * 16 + k) * 4 + c] = sum;
      }
      p[(i * 16 + k) * 4 + 3] = 1;
    }
  }
  return p;
}
