// The test's own reading of an aobake GLB, independent of three.js and of
// the viewer: GLB chunks, the AOBAKE_lightmap extension, PNG decoding
// (pngjs), bilinear sampling as the contract's sampler does at mip level
// 0, and the CPU relight sum_i c_i L_i.

import { PNG } from 'pngjs';

/** { json, bin } of a GLB. */
export function readGlb(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (view.getUint32(0, true) !== 0x46546c67) throw new Error('not a GLB');
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const binStart = 20 + jsonLength + 8;
  const bin = bytes.subarray(binStart, binStart + view.getUint32(20 + jsonLength, true));
  return { json, bin };
}

/** A GLB from JSON and BIN (for malformed variants). */
export function writeGlb(json, bin) {
  let text = Buffer.from(JSON.stringify(json));
  text = Buffer.concat([text, Buffer.alloc((4 - (text.length % 4)) % 4, 0x20)]);
  const binPadded = Buffer.concat([Buffer.from(bin), Buffer.alloc((4 - (bin.length % 4)) % 4)]);
  const total = 12 + 8 + text.length + 8 + binPadded.length;
  const header = Buffer.alloc(12);
  header.writeUInt32LE(0x46546c67, 0);
  header.writeUInt32LE(2, 4);
  header.writeUInt32LE(total, 8);
  const chunk = (len, type) => {
    const b = Buffer.alloc(8);
    b.writeUInt32LE(len, 0);
    b.write(type, 4, 'latin1');
    return b;
  };
  return Buffer.concat([header, chunk(text.length, 'JSON'), text, chunk(binPadded.length, 'BIN\0'), binPadded]);
}

/** The decoded RGBA8 image of textures[index]. */
export function textureImage({ json, bin }, index) {
  const image = json.images[json.textures[index].source];
  const view = json.bufferViews[image.bufferView];
  const bytes = bin.subarray(view.byteOffset ?? 0, (view.byteOffset ?? 0) + view.byteLength);
  const png = PNG.sync.read(Buffer.from(bytes));
  return { width: png.width, height: png.height, data: png.data };
}

/**
 * Channel `c` of `img` at (u, v), bilinear over texel centres at
 * ((i + 0.5) / W, (j + 0.5) / H), clamped to the edge, in [0, 1].
 */
export function bilinear(img, u, v, c) {
  const x = u * img.width - 0.5;
  const y = v * img.height - 0.5;
  const x0 = Math.floor(x);
  const y0 = Math.floor(y);
  const fx = x - x0;
  const fy = y - y0;
  const at = (i, j) => {
    const ci = Math.min(img.width - 1, Math.max(0, i));
    const cj = Math.min(img.height - 1, Math.max(0, j));
    return img.data[(cj * img.width + ci) * 4 + c] / 255;
  };
  return (
    (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) +
    fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1))
  );
}

/**
 * Channel `c` of `img` at (u, v) through the contract's bicubic lookup
 * (`"filter": "bicubic"`): the uniform cubic B-spline over the 4 x 4
 * texels around (u, v), indices clamped to the edge, written out here from
 * the spec's formula (16 taps, not the shader's four bilinear fetches).
 */
export function bspline(img, u, v, c) {
  const x = u * img.width - 0.5;
  const y = v * img.height - 0.5;
  const x0 = Math.floor(x);
  const y0 = Math.floor(y);
  const B = (s) => [(1 - s) ** 3 / 6, (3 * s ** 3 - 6 * s ** 2 + 4) / 6, (-3 * s ** 3 + 3 * s ** 2 + 3 * s + 1) / 6, s ** 3 / 6];
  const wx = B(x - x0);
  const wy = B(y - y0);
  let out = 0;
  for (let b = 0; b < 4; b++) {
    const j = Math.min(img.height - 1, Math.max(0, y0 - 1 + b));
    for (let a = 0; a < 4; a++) {
      const i = Math.min(img.width - 1, Math.max(0, x0 - 1 + a));
      out += wx[a] * wy[b] * (img.data[(j * img.width + i) * 4 + c] / 255);
    }
  }
  return out;
}

/** Every baked primitive's extension; the atlas is shared, so one. */
export function lightmapOf(glb) {
  const exts = [];
  for (const mesh of glb.json.meshes) {
    for (const p of mesh.primitives) {
      const e = p.extensions?.AOBAKE_lightmap;
      if (e) exts.push(e);
    }
  }
  return exts;
}

/** The 9 coefficients c_i at (u, v), decoded per the contract, read with
 * `sample` (bilinear, or bspline for a bicubic file). */
export function coefficientsAt(images, ext, u, v, sample = bilinear) {
  const [, sh0, sh1, sh2] = images;
  const ch = [
    sample(sh0, u, v, 0), sample(sh0, u, v, 1), sample(sh0, u, v, 2), sample(sh0, u, v, 3),
    sample(sh1, u, v, 0), sample(sh1, u, v, 1), sample(sh1, u, v, 2), sample(sh1, u, v, 3),
    sample(sh2, u, v, 0),
  ];
  return ch.map((x, i) => ext.shScale[i] * x + ext.shOffset[i]);
}

/** The real SH basis of the contract, written out again from its table. */
export function basis([x, y, z]) {
  return [
    0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x,
    1.092548 * x * y, 1.092548 * y * z, 0.315392 * (3 * z * z - 1),
    1.092548 * x * z, 0.546274 * (x * x - y * y),
  ];
}

/**
 * SH coefficients of a scalar radiance function by quadrature over a
 * Fibonacci sphere (a different rule from the viewer's latitude-longitude
 * grid).
 */
export function projectScalar(radiance, n = 200000) {
  const out = new Array(9).fill(0);
  const golden = Math.PI * (3 - Math.sqrt(5));
  for (let k = 0; k < n; k++) {
    const y = 1 - (2 * (k + 0.5)) / n;
    const r = Math.sqrt(1 - y * y);
    const w = [r * Math.cos(golden * k), y, r * Math.sin(golden * k)];
    const L = radiance(w);
    const Y = basis(w);
    for (let i = 0; i < 9; i++) out[i] += (L * Y[i] * 4 * Math.PI) / n;
  }
  return out;
}

/** The visibility layer v_0..v_15 at (u, v) (9 at order 2, the rest 0). */
export function visibilityAt(images, ext, u, v) {
  const out = new Array(16).fill(0);
  for (let i = 0; i < ext.visibilityScale.length; i++) {
    const x = bilinear(images[Math.floor(i / 4)], u, v, i % 4);
    out[i] = ext.visibilityScale[i] * x + ext.visibilityOffset[i];
  }
  return out;
}

/** The contract's 16 basis functions (bands 0..3), from its tables. */
export function basis16(w) {
  const [x, y, z] = w;
  return [
    ...basis(w),
    0.590044 * y * (3 * x * x - y * y), 2.890611 * x * y * z,
    0.457046 * y * (5 * z * z - 1), 0.373176 * z * (5 * z * z - 3),
    0.457046 * x * (5 * z * z - 1), 1.445306 * z * (x * x - y * y),
    0.590044 * x * (x * x - 3 * y * y),
  ];
}

let triple = null;
/**
 * The SH triple product Int Y_i Y_j Y_k dw (i, k < 16, j < 9) by a fine
 * midpoint rule in (cos theta, phi) (another rule than the plugin's
 * Gauss-Legendre): t[i][j][k].
 */
export function tripleProduct() {
  if (triple) return triple;
  triple = Array.from({ length: 16 }, () => Array.from({ length: 9 }, () => new Array(16).fill(0)));
  const nz = 160;
  const np = 320;
  const dw = (2 / nz) * ((2 * Math.PI) / np);
  for (let a = 0; a < nz; a++) {
    const z = -1 + (2 * (a + 0.5)) / nz;
    const r = Math.sqrt(1 - z * z);
    for (let b = 0; b < np; b++) {
      const phi = ((b + 0.5) / np) * 2 * Math.PI;
      const y = basis16([r * Math.cos(phi), r * Math.sin(phi), z]);
      for (let i = 0; i < 16; i++) {
        for (let j = 0; j < 9; j++) {
          const yij = y[i] * y[j] * dw;
          for (let k = 0; k < 16; k++) triple[i][j][k] += yij * y[k];
        }
      }
    }
  }
  return triple;
}

/**
 * The README's anchored diffuse for one colour channel: c.L + E_C(n')/pi -
 * E_C(n)/pi with u = P^T v, P_ik = sum_j Gamma_ijk L_j.
 */
export function anchoredDiffuse(c, v, L, n, nPrime) {
  const t = tripleProduct();
  const u = new Array(16).fill(0);
  for (let i = 0; i < 16; i++) {
    if (v[i] === 0) continue;
    for (let k = 0; k < 16; k++) {
      let p = 0;
      for (let j = 0; j < 9; j++) p += t[i][j][k] * L[j];
      u[k] += v[i] * p;
    }
  }
  const A = [Math.PI, (2 * Math.PI) / 3, Math.PI / 4];
  const band = [0, 1, 1, 1, 2, 2, 2, 2, 2];
  const at = (m) => {
    const y = basis(m);
    let e = 0;
    for (let k = 0; k < 9; k++) e += A[band[k]] * u[k] * y[k];
    return e / Math.PI;
  };
  const cl = c.reduce((s, ci, i) => s + ci * L[i], 0);
  return cl + at(nPrime) - at(n);
}

/**
 * The shader's normal-mapped diffuse against anchoredDiffuse at probe
 * pixels (one colour channel). `probes` holds per-pixel debug outputs:
 * uv, mapped, irradiance (c.L), shadingNormal and vertexNormal (normals as
 * 0.5 + 0.5 n). Returns the pixels compared, the largest difference, how
 * many the normal maps moved by more than 1% of the largest |L_i|, and
 * that scale.
 */
export function anchoredAgreement(probes, images, vImages, ext, L) {
  const { uv, mapped, irradiance, shadingNormal, vertexNormal } = probes;
  const unit = (p) => {
    const v = [2 * p[0] - 1, 2 * p[1] - 1, 2 * p[2] - 1];
    const len = Math.hypot(...v);
    return v.map((x) => x / len);
  };
  const scale = Math.max(...L.map(Math.abs));
  let n = 0;
  let worst = 0;
  let moved = 0;
  for (let k = 0; k < uv.length; k++) {
    if ([uv, mapped, shadingNormal, vertexNormal].some((r) => r[k][3] !== 1)) continue;
    const c = coefficientsAt(images, ext, uv[k][0], uv[k][1]);
    const v = visibilityAt(vImages, ext, uv[k][0], uv[k][1]);
    const expected = anchoredDiffuse(c, v, L, unit(vertexNormal[k]), unit(shadingNormal[k]));
    worst = Math.max(worst, Math.abs(mapped[k][0] - expected));
    if (Math.abs(mapped[k][0] - irradiance[k][0]) > 0.01 * scale) moved++;
    n++;
  }
  return { n, worst, moved, scale };
}

/** The largest |a - b| of the first channel over the pixels `a` covers
 * (alpha 1): two probes of the same view. */
export function largestDifference(a, b) {
  let worst = 0;
  for (let k = 0; k < a.length; k++) {
    if (a[k][3] === 1) worst = Math.max(worst, Math.abs(a[k][0] - b[k][0]));
  }
  return worst;
}
