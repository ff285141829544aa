// Environments for the viewer: radiance as a function of a world direction,
// projected onto the 9 real SH coefficients of the contract's basis (the
// basis of three's SphericalHarmonics3), rotated about the vertical axis.
//
// In: a built-in name, or an equirectangular image's pixels; a rotation.
// Out: 9 RGB coefficients L_i with L(w) ~ sum_i L_i Y_i(w).

/** Y_i(w) for w = (x, y, z), the contract's order. */
export function shBasis(x, y, z) {
  return [
    0.282095,
    0.488603 * y,
    0.488603 * z,
    0.488603 * x,
    1.092548 * x * y,
    1.092548 * y * z,
    0.315392 * (3 * z * z - 1),
    1.092548 * x * z,
    0.546274 * (x * x - y * y),
  ];
}

/** A smooth lobe of white light around unit direction d: max(0, w.d)^4 x scale. */
export function lobe(d, scale = 1) {
  return (x, y, z) => {
    const c = Math.max(0, x * d[0] + y * d[1] + z * d[2]);
    const v = scale * c * c * c * c;
    return [v, v, v];
  };
}

/** The built-in environments (radiance, linear RGB). */
export const BUILT_IN = {
  white: { label: 'uniform white (L0 only)', radiance: () => [1, 1, 1] },
  sky: {
    label: 'sky',
    radiance: (x, y) => {
      if (y >= 0) {
        const t = Math.pow(y, 0.5);
        return [0.9 - 0.5 * t, 0.95 - 0.3 * t, 1.0];
      }
      return [0.25, 0.2, 0.15];
    },
  },
  sunset: {
    label: 'sunset (warm from +X, cool sky)',
    radiance: (x, y, z) => {
      const sun = Math.max(0, 0.8 * x + 0.6 * y);
      const s = 4 * Math.pow(sun, 6);
      const sky = y > 0 ? 0.25 : 0.05;
      return [sky * 0.6 + s, sky * 0.7 + 0.55 * s, sky * 1.2 + 0.2 * s];
    },
  },
  'lobe+x': { label: 'light from +X', radiance: lobe([1, 0, 0], 3) },
  'lobe-x': { label: 'light from -X', radiance: lobe([-1, 0, 0], 3) },
  'lobe+y': { label: 'light from +Y', radiance: lobe([0, 1, 0], 3) },
  'lobe-y': { label: 'light from -Y', radiance: lobe([0, -1, 0], 3) },
};

/** Grid of the projection: rows in latitude, columns in longitude. */
const ROWS = 96;
const COLS = 192;

/**
 * The SH coefficients (9 x [r, g, b]) of `radiance(x, y, z)` rotated by
 * `rotation` radians about +Y (the environment turns, the scene stays):
 * a midpoint rule over latitude-longitude cells weighted by solid angle.
 */
export function project(radiance, rotation = 0) {
  const out = Array.from({ length: 9 }, () => [0, 0, 0]);
  const [cr, sr] = [Math.cos(rotation), Math.sin(rotation)];
  for (let i = 0; i < ROWS; i++) {
    const theta = ((i + 0.5) / ROWS) * Math.PI;
    const y = Math.cos(theta);
    const ring = Math.sin(theta);
    const weight = ring * (Math.PI / ROWS) * ((2 * Math.PI) / COLS);
    for (let j = 0; j < COLS; j++) {
      const phi = ((j + 0.5) / COLS) * 2 * Math.PI;
      const x = ring * Math.cos(phi);
      const z = ring * Math.sin(phi);
      // The environment rotated by R is L(R^-1 w).
      const L = radiance(cr * x - sr * z, y, sr * x + cr * z);
      const Y = shBasis(x, y, z);
      for (let k = 0; k < 9; k++) {
        const w = Y[k] * weight;
        out[k][0] += L[0] * w;
        out[k][1] += L[1] * w;
        out[k][2] += L[2] * w;
      }
    }
  }
  return out;
}

/** sRGB-encoded 8-bit value to linear. */
function srgbToLinear(v) {
  const c = v / 255;
  return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
}

/**
 * Radiance of an equirectangular image (RGBA8 pixels, sRGB): +Y at the top
 * row, longitude 0 at the image's centre looking along -Z (three's
 * equirectangular convention).
 */
export function equirect(pixels, width, height) {
  return (x, y, z) => {
    const u = 0.5 + Math.atan2(x, -z) / (2 * Math.PI);
    const v = Math.acos(Math.max(-1, Math.min(1, y))) / Math.PI;
    const px = Math.min(width - 1, Math.floor(u * width));
    const py = Math.min(height - 1, Math.floor(v * height));
    const o = (py * width + px) * 4;
    return [srgbToLinear(pixels[o]), srgbToLinear(pixels[o + 1]), srgbToLinear(pixels[o + 2])];
  };
}
