// Babylon.js importer for aobake's `AOBAKE_lightmap` glTF extension.
//
// In: a glTF written by aobake (the contract: docs/extensions/AOBAKE_lightmap,
// per baked primitive `{texCoord, occlusion, sh[3], shScale[9], shOffset[9]}`
// and, with several atlas pages, `page`), loaded by @babylonjs/loaders' glTF
// 2.0 loader, and the scene's environment (its `environmentTexture`'s
// spherical polynomial, or radiance SH given directly). Out: every baked
// primitive's material (cloned per material and page, since each page has
// its own textures and ranges) carries a MaterialPlugin that replaces the
// PBR material's diffuse environment light by the baked one:
//   finalIrradiance = sum_i c_i L_i,  c_i = shScale[i] * channel_i + shOffset[i]
// read bilinearly on the extension's UV set; the baked AO sits on the
// material's ambient (occlusion) slot, where every Babylon material shows it.
//
// Conventions (checked by the repository's babylon/test/babylon.test.mjs):
// - basis and order: the contract's real SH, (l,m) = (0,0),(1,-1),(1,0),(1,1),
//   (2,-2),(2,-1),(2,0),(2,1),(2,2), no Condon-Shortley phase; Babylon's
//   SphericalHarmonics carry the phase (l1_1, l11, l2_1, l21 negated), so its
//   coefficients are not used directly;
// - scale: c_i carries the 1/pi, so sum_i c_i L_i = E / pi, which is what
//   Babylon's `reflectionOut.environmentIrradiance` holds (its polynomial is
//   the irradiance over pi, before albedo); the plugin puts c.L in its place;
// - world space: the bake's directions are the file's (glTF, right-handed, Y
//   up). The loader's root node maps them into Babylon's world (a mirror
//   unless the scene is right-handed); the environment's L_i are projected
//   through that root's matrix, numerically, so any root transform works;
// - channels: c0..c3 = sh[0].rgba, c4..c7 = sh[1].rgba, c8 = sh[2].r; the
//   textures hold linear data (gammaSpace false), clamp to edge.
//
// The visibility layer (`visibility[4|3]`, v_i = Int V H(n.w) Y_i dw, 16 or
// 9 coefficients), where a primitive has it, lets the normal map drive the
// baked light exactly as the three.js plugin does (the contract's formula):
// per environment P_ik = sum_j Gamma_ijk L_j (a 16 x 16 float texture), per
// fragment u = P^T v and E(n')/pi = c.L + E_C(n')/pi - E_C(n)/pi, with n the
// vertex normal and n' Babylon's normal-mapped one, both taken back into the
// bake's frame (normals by M^T, M the root's linear part); and the indirect
// specular is occluded by the lobe-filtered visible radiance over an open
// receiver's (in place of Babylon's AO-based radiance occlusion). Without
// the layer, the specular is occluded by the contract's fallback, the cone
// of the AO around the bent normal from c (as in the three.js plugin; in
// place of Babylon's radiance occlusion).
//
// Imports: @babylonjs/core and @babylonjs/loaders (peer dependencies),
// this package's glsl.js (the bake's GLSL in Babylon's shader), and the
// engine-neutral contract it shares with the three.js plugin, the package
// aobake-contract (the extension's name and checks; the SH basis,
// quadrature, Gamma and P; and, through glsl.js, the shared formulas).
//
// Use:
//   import { registerAobakeLightmap, AobakeLightmaps } from 'aobake-babylon';
//   const lightmaps = new AobakeLightmaps();
//   registerAobakeLightmap(lightmaps);
//   await SceneLoader.AppendAsync(url, undefined, scene);   // or ImportMeshAsync
//   lightmaps.setEnvironmentFromScene(scene);  // or setEnvironment(L) (9 x [r,g,b])
//   lightmaps.setMode('sh');                    // 'sh' | 'ao' | 'off'

import { MaterialPluginBase } from '@babylonjs/core/Materials/materialPluginBase.js';
import { Texture } from '@babylonjs/core/Materials/Textures/texture.js';
import { registerGLTFExtension } from '@babylonjs/loaders/glTF/2.0/glTFLoaderExtensionRegistry.js';
import { RawTexture } from '@babylonjs/core/Materials/Textures/rawTexture.js';
import { RenderTargetTexture } from '@babylonjs/core/Materials/Textures/renderTargetTexture.js';
import { Color4 } from '@babylonjs/core/Maths/math.color.js';
import { Constants } from '@babylonjs/core/Engines/constants.js';
import {
  BICUBIC_GLSL,
  EXTENSION,
  basis9,
  extensionProblem as contractProblem,
  filterOf,
  project,
  radianceProduct,
} from 'aobake-contract';
import { FALLBACK_GLSL, FRAME_GLSL, LAYER_GLSL } from './glsl.js';

export { EXTENSION };

/** Output modes: 'sh' the baked light relit, 'ao' Babylon's environment
 * light times the baked AO (its ambient slot), 'off' no baked light. */
export const MODES = { off: 0, ao: 1, sh: 2 };

/** Debug outputs (raw, for tests): c.L, the AO texture, the lightmap UV,
 * the atlas page, (u, v, red of c.L, page + 1) from one fragment, and
 * Babylon's own diffuse environment light E/pi (what 'sh' replaces). */
export const DEBUG = {
  none: 0, irradiance: 1, ao: 2, uv: 3, page: 4, uvIrradiancePage: 5, environment: 6,
  // With the visibility layer: the normal-mapped diffuse over pi (the
  // anchored formula), the shading normal n' and the vertex normal n in
  // the bake's frame as 0.5 + 0.5 n, and the specular occlusion.
  mapped: 7, shadingNormal: 8, vertexNormal: 9, specularOcclusion: 10,
};

export { basis9, project };

/** Band of coefficient i. */
const band = (i) => (i === 0 ? 0 : i < 4 ? 1 : 2);

/** The cosine lobe's convolution A_l (Ramamoorthi and Hanrahan). */
const A = [Math.PI, (2 * Math.PI) / 3, Math.PI / 4];

/** Babylon's SH terms without their constants (its `applySH3` order). */
const TRIG = [
  () => 1, (d) => d[1], (d) => d[2], (d) => d[0], (d) => d[0] * d[1], (d) => d[1] * d[2],
  (d) => 3 * d[2] * d[2] - 1, (d) => d[0] * d[2], (d) => d[0] * d[0] - d[1] * d[1],
];

/**
 * Radiance SH L_i in the bake's (glTF world) frame from a Babylon
 * environment's spherical polynomial and the 3x3 linear part `toScene`
 * (row-major) of the glTF root's world matrix.
 *
 * What Babylon's PBR shader evaluates for the diffuse environment light is
 * E(n)/pi = sum_k h_k t_k(n) with h = `preScaledHarmonics` (its constants,
 * phase and the cosine lobe folded in) and t_k the bare terms: that
 * function, at n = M w, is projected on the contract's basis and divided by
 * the lobe's A_l / pi, so an open receiver relights as Babylon lights it.
 * (The polynomial's own coefficients are not that function: its band 1 is
 * 2/3 of it, measured by babylon/test.)
 */
export function radianceFromPolynomial(poly, toScene) {
  const m = toScene;
  const hs = poly.preScaledHarmonics;
  const h = [hs.l00, hs.l1_1, hs.l10, hs.l11, hs.l2_2, hs.l2_1, hs.l20, hs.l21, hs.l22];
  const e = (d) => {
    let x = m[0] * d[0] + m[1] * d[1] + m[2] * d[2];
    let y = m[3] * d[0] + m[4] * d[1] + m[5] * d[2];
    let z = m[6] * d[0] + m[7] * d[1] + m[8] * d[2];
    const len = Math.hypot(x, y, z) || 1;
    const n = [x / len, y / len, z / len];
    const t = TRIG.map((f) => f(n));
    return [0, 1, 2].map((c) => h.reduce((s, v, k) => s + [v.x, v.y, v.z][c] * t[k], 0));
  };
  return project(e).map((p, i) => p.map((v) => (v * Math.PI) / A[band(i)]));
}

/** Why an extension object cannot be used, or null: the contract's rules
 * (shared with the three.js plugin), and a UV set Babylon's PBR material
 * can carry. */
export function extensionProblem(ext, json) {
  const problem = contractProblem(ext, json);
  if (problem) return problem;
  if (ext.texCoord > 3) return `texCoord ${ext.texCoord} is past the sets this importer reads (0..3)`;
  return null;
}

/** What the importer found, and the state every patched material shares. */
export class AobakeLightmaps {
  constructor() {
    /** 9 x [r, g, b]: the environment's radiance SH in the bake's frame. */
    this.L = Array.from({ length: 9 }, () => [0, 0, 0]);
    this.mode = MODES.sh;
    this.debug = DEBUG.none;
    /** Baked meshes: { mesh, label, extension, material, textures }. */
    this.baked = [];
    /** One line per primitive whose extension could not be used. */
    this.problems = [];
    /** The root extension of the last file. */
    this.record = null;
    /** The lookup the last file's texels are fitted for ('bilinear' or
     * 'bicubic', the root's `filter`), and a test's override of it. */
    this.filter = 'bilinear';
    this._filterOverride = null;
    /** Row-major 3x3: glTF world directions to the scene's (the loader's root). */
    this.toScene = [1, 0, 0, 0, 1, 0, 0, 0, 1];
    this._scene = null;
    /** P (16 x 16 RGBA float), made once a scene is known. */
    this.product = null;
  }

  /** Radiance SH in the bake's frame, 9 x [r, g, b]. */
  setEnvironment(L) {
    this.L = L.map((c) => [c[0], c[1], c[2]]);
    this.product?.update(radianceProduct(this.L));
    this._scene?.resetCachedMaterial();
  }

  /** The scene's own environment (environmentTexture.sphericalPolynomial),
   * converted; returns the L_i set. */
  setEnvironmentFromScene(scene) {
    const poly = scene.environmentTexture?.sphericalPolynomial;
    if (!poly) throw new Error('the scene has no environment texture with spherical harmonics');
    this.setEnvironment(radianceFromPolynomial(poly, this.toScene));
    return this.L;
  }

  setMode(mode) {
    if (!(mode in MODES)) throw new Error(`unknown mode ${mode}`);
    this.mode = MODES[mode];
    // The mode decides which occlusion the specular gets (a define).
    for (const b of this.baked) b.material.markAsDirty(1);
    this._scene?.resetCachedMaterial();
  }

  /** The lookup the materials sample with: the file's, unless overridden. */
  get lookup() {
    return this._filterOverride ?? this.filter;
  }

  /** Samples with 'bilinear' or 'bicubic' whatever the file says, or
   * (null) as the file says: to compare the two paths on one file. */
  setFilter(name) {
    if (name !== null && name !== 'bilinear' && name !== 'bicubic') throw new Error(`unknown filter ${name}`);
    this._filterOverride = name;
    // The lookup is a define.
    for (const b of this.baked) b.material.markAsDirty(1);
    this._scene?.resetCachedMaterial();
  }

  setDebug(name) {
    if (!(name in DEBUG)) throw new Error(`unknown debug output ${name}`);
    this.debug = DEBUG[name];
    this._scene?.resetCachedMaterial();
  }

  /** Bilinear at mip level 0 (as a CPU decoder reads), or trilinear. */
  setLevel0(on) {
    for (const b of this.baked) {
      for (const t of b.textures) {
        t.updateSamplingMode(on ? Texture.BILINEAR_SAMPLINGMODE : Texture.TRILINEAR_SAMPLINGMODE);
      }
    }
  }

  /** Normal maps on (the materials' own) or off (removed: the shading
   * normal is then the vertex normal, and the bake relights as c.L). */
  setNormalMaps(on) {
    for (const b of this.baked) {
      const m = b.material;
      if (!on && m.bumpTexture) {
        b.bump = m.bumpTexture;
        m.bumpTexture = null;
      } else if (on && b.bump) {
        m.bumpTexture = b.bump;
        b.bump = null;
      }
    }
  }

  /**
   * Renders the baked meshes of `scene` through `camera` with debug output
   * `debug` (raw floats, lightmaps at level 0) and returns [r, g, b, a] at
   * each pixel [x, y] (from the top left) of a `width` x `height` frame;
   * a = 0 where no baked mesh is. For tests and diagnostics.
   */
  async probe(scene, camera, debug, pixels, [width, height]) {
    const rtt = new RenderTargetTexture('aobake probe', { width, height }, scene, {
      generateMipMaps: false, type: Constants.TEXTURETYPE_FLOAT,
    });
    rtt.renderList = this.baked.map((b) => b.mesh);
    rtt.activeCamera = camera;
    rtt.clearColor = new Color4(0, 0, 0, 0);
    this.setLevel0(true);
    this.setDebug(debug);
    const wait = (ms) => new Promise((r) => setTimeout(r, ms));
    await new Promise((ok) => scene.executeWhenReady(ok));
    for (let k = 0; k < 200 && !rtt.isReadyForRendering(); k++) await wait(20);
    // Shaders compile asynchronously (isReady starts them): wait until
    // every material is ready, then render once (a software rasterizer
    // takes seconds a frame on a large model).
    for (let k = 0; k < 200 && !rtt.renderList.every((m) => m.material.isReady(m)); k++) await wait(50);
    rtt.render();
    const data = await rtt.readPixels();
    this.setDebug('none');
    this.setLevel0(false);
    rtt.dispose();
    return pixels.map(([x, y]) => {
      const o = ((height - 1 - y) * width + x) * 4;
      return [data[o], data[o + 1], data[o + 2], data[o + 3]];
    });
  }

  /** The shared P texture of `scene`. */
  _productFor(scene) {
    if (!this.product || this.product.getScene() !== scene) {
      this.product = new RawTexture(radianceProduct(this.L), 16, 16, Constants.TEXTUREFORMAT_RGBA, scene,
        false, false, Texture.NEAREST_SAMPLINGMODE, Constants.TEXTURETYPE_FLOAT);
      this.product.name = 'aobake P';
    }
    return this.product;
  }

  clear() {
    this.baked = [];
    this.problems = [];
    this.record = null;
    this.filter = 'bilinear';
  }
}

/** Rows of M^T and M^-1 for M (row-major 3x3): normals and directions of
 * the scene into the bake's frame. */
export function toBakeRows(m) {
  const det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) + m[2] * (m[3] * m[7] - m[4] * m[6]);
  const inv = [
    m[4] * m[8] - m[5] * m[7], m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
    m[5] * m[6] - m[3] * m[8], m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
    m[3] * m[7] - m[4] * m[6], m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3],
  ].map((v) => v / (det || 1));
  const normal = [[m[0], m[3], m[6]], [m[1], m[4], m[7]], [m[2], m[5], m[8]]];
  const direction = [inv.slice(0, 3), inv.slice(3, 6), inv.slice(6, 9)];
  return { normal, direction };
}

/** The material plugin: c.L in place of the PBR diffuse environment light,
 * and with the layer the normal-mapped diffuse and specular occlusion. */
export class AobakeLightmapPlugin extends MaterialPluginBase {
  constructor(material, lightmaps, bake) {
    super(material, 'AobakeLightmap', 200, { AOBAKE: false, AOBAKE_UVSET: 0, AOBAKE_VISIBILITY: false, AOBAKE_VCOUNT: 16, AOBAKE_BICUBIC: false });
    this.lightmaps = lightmaps;
    // { texCoord, occlusion, sh: [3 textures], scale[9], offset[9], page,
    //   visibility: [3|4 textures] | null, vScale[], vOffset[] }
    this.bake = bake;
    this._enable(true);
  }

  getClassName() {
    return 'AobakeLightmapPlugin';
  }

  prepareDefines(defines) {
    defines.AOBAKE = true;
    defines.AOBAKE_UVSET = this.bake.texCoord + 1;
    const layer = this.bake.visibility !== null;
    defines.AOBAKE_VISIBILITY = layer;
    defines.AOBAKE_VCOUNT = layer ? this.bake.vScale.length : 16;
    defines.AOBAKE_BICUBIC = this.lightmaps.lookup === 'bicubic';
    // With the baked light on, the bake occludes the specular (the layer,
    // or the contract's cone of the AO without it, as the three.js plugin
    // does); Babylon's AO-based radiance occlusion would do it twice.
    if (this.lightmaps.mode === MODES.sh) defines.RADIANCEOCCLUSION = false;
  }

  getAttributes(attributes, scene, mesh) {
    const name = this.bake.texCoord === 0 ? 'uv' : `uv${this.bake.texCoord + 1}`;
    if (mesh.isVerticesDataPresent(name) && !attributes.includes(name)) attributes.push(name);
  }

  getSamplers(samplers) {
    samplers.push('aobakeSH0', 'aobakeSH1', 'aobakeSH2', 'aobakeAO', 'aobakeV0', 'aobakeV1', 'aobakeV2', 'aobakeV3', 'aobakeP');
  }

  getUniforms() {
    const v4 = ['aobakeScale0', 'aobakeScale1', 'aobakeScale2', 'aobakeOffset0', 'aobakeOffset1', 'aobakeOffset2',
      'aobakeVScale0', 'aobakeVScale1', 'aobakeVScale2', 'aobakeVScale3',
      'aobakeVOffset0', 'aobakeVOffset1', 'aobakeVOffset2', 'aobakeVOffset3'];
    const v3 = [...Array.from({ length: 9 }, (_, i) => `aobakeL${i}`),
      'aobakeNormalRow0', 'aobakeNormalRow1', 'aobakeNormalRow2',
      'aobakeDirectionRow0', 'aobakeDirectionRow1', 'aobakeDirectionRow2'];
    const f = ['aobakeMode', 'aobakeDebug', 'aobakePage'];
    const ubo = [
      ...v4.map((name) => ({ name, size: 4, type: 'vec4' })),
      ...v3.map((name) => ({ name, size: 3, type: 'vec3' })),
      ...f.map((name) => ({ name, size: 1, type: 'float' })),
    ];
    const fragment = `#ifdef AOBAKE
${v4.map((n) => `uniform vec4 ${n};`).join('\n')}
${v3.map((n) => `uniform vec3 ${n};`).join('\n')}
${f.map((n) => `uniform float ${n};`).join('\n')}
#endif`;
    return { ubo, fragment };
  }

  bindForSubMesh(uniformBuffer) {
    const b = this.bake;
    const lm = this.lightmaps;
    const v4 = (a, k) => [a[k] ?? 0, a[k + 1] ?? 0, a[k + 2] ?? 0, a[k + 3] ?? 0];
    for (let j = 0; j < 3; j++) {
      uniformBuffer.updateFloat4(`aobakeScale${j}`, ...v4(b.scale, 4 * j));
      uniformBuffer.updateFloat4(`aobakeOffset${j}`, ...v4(b.offset, 4 * j));
    }
    for (let j = 0; j < 4; j++) {
      uniformBuffer.updateFloat4(`aobakeVScale${j}`, ...v4(b.vScale, 4 * j));
      uniformBuffer.updateFloat4(`aobakeVOffset${j}`, ...v4(b.vOffset, 4 * j));
    }
    for (let i = 0; i < 9; i++) uniformBuffer.updateFloat3(`aobakeL${i}`, ...lm.L[i]);
    const rows = toBakeRows(lm.toScene);
    for (let r = 0; r < 3; r++) {
      uniformBuffer.updateFloat3(`aobakeNormalRow${r}`, ...rows.normal[r]);
      uniformBuffer.updateFloat3(`aobakeDirectionRow${r}`, ...rows.direction[r]);
    }
    uniformBuffer.updateFloat('aobakeMode', lm.mode);
    uniformBuffer.updateFloat('aobakeDebug', lm.debug);
    uniformBuffer.updateFloat('aobakePage', b.page);
    uniformBuffer.setTexture('aobakeSH0', b.sh[0]);
    uniformBuffer.setTexture('aobakeSH1', b.sh[1]);
    uniformBuffer.setTexture('aobakeSH2', b.sh[2]);
    uniformBuffer.setTexture('aobakeAO', b.occlusion);
    if (b.visibility) {
      for (let j = 0; j < 4; j++) uniformBuffer.setTexture(`aobakeV${j}`, b.visibility[Math.min(j, b.visibility.length - 1)]);
      uniformBuffer.setTexture('aobakeP', lm._productFor(this._material.getScene()));
    }
  }

  getActiveTextures(active) {
    active.push(...this.bake.sh, this.bake.occlusion, ...(this.bake.visibility ?? []));
  }

  hasTexture(texture) {
    return this.bake.sh.includes(texture) || this.bake.occlusion === texture || (this.bake.visibility ?? []).includes(texture);
  }

  getCustomCode(shaderType) {
    const uv = (set) => (set === 1 ? 'uv' : `uv${set}`);
    if (shaderType === 'vertex') {
      const sets = [1, 2, 3, 4];
      return {
        CUSTOM_VERTEX_DEFINITIONS: `#ifdef AOBAKE
${sets.map((s) => `#if AOBAKE_UVSET == ${s} && !defined(UV${s})
attribute vec2 ${uv(s)};
#endif`).join('\n')}
varying vec2 vAobakeUV;
#endif`,
        CUSTOM_VERTEX_MAIN_END: `#ifdef AOBAKE
${sets.map((s) => `#if AOBAKE_UVSET == ${s}
vAobakeUV = ${uv(s)};
#endif`).join('\n')}
#endif`,
      };
    }
    if (shaderType !== 'fragment') return null;
    return {
      CUSTOM_FRAGMENT_DEFINITIONS: `#ifdef AOBAKE
varying vec2 vAobakeUV;
uniform sampler2D aobakeSH0;
uniform sampler2D aobakeSH1;
uniform sampler2D aobakeSH2;
uniform sampler2D aobakeAO;
// Level 0 (bilinear, as a CPU decoder reads) for the debug outputs: the
// sampler's own minification would average a sliver's texels.
#ifdef AOBAKE_BICUBIC
// The file's texels are cubic B-spline coefficients (the root's filter).
#define AOBAKE_FETCH(s, uv) (aobakeDebug > 0.5 ? texture2DLodEXT(s, uv, 0.0) : texture2D(s, uv))
${BICUBIC_GLSL}
vec4 aobakeTexel(sampler2D s) {
  return aobakeBicubic(s, vAobakeUV);
}
#else
vec4 aobakeTexel(sampler2D s) {
  return aobakeDebug > 0.5 ? texture2DLodEXT(s, vAobakeUV, 0.0) : texture2D(s, vAobakeUV);
}
#endif
vec3 aobakeIrradiance() {
  vec4 a = aobakeTexel(aobakeSH0) * aobakeScale0 + aobakeOffset0;
  vec4 b = aobakeTexel(aobakeSH1) * aobakeScale1 + aobakeOffset1;
  float c8 = aobakeTexel(aobakeSH2).r * aobakeScale2.x + aobakeOffset2.x;
  return a.x * aobakeL0 + a.y * aobakeL1 + a.z * aobakeL2 + a.w * aobakeL3
    + b.x * aobakeL4 + b.y * aobakeL5 + b.z * aobakeL6 + b.w * aobakeL7 + c8 * aobakeL8;
}
#ifdef AOBAKE_VISIBILITY
uniform sampler2D aobakeV0;
uniform sampler2D aobakeV1;
uniform sampler2D aobakeV2;
uniform sampler2D aobakeV3;
uniform highp sampler2D aobakeP;
${LAYER_GLSL}
#else
${FALLBACK_GLSL}
#endif
${FRAME_GLSL}
// The vertex normal n with Babylon's own two-sided flip (as normalW gets).
vec3 aobakeVertexNormal(vec3 n) {
#if defined(TWOSIDEDLIGHTING) && defined(NORMAL)
#if defined(MIRRORED)
  n = gl_FrontFacing ? -n : n;
#else
  n = gl_FrontFacing ? n : -n;
#endif
#endif
  return n;
}
// The specular occlusion at the fragment, from main()'s variables: one
// expression for the render and the debug output.
#define AOBAKE_SPECULAR_OCCLUSION() aobakeSpecularOcclusion(aobakeNormalToBake(aobakeVertexNormal(geometricNormalW)), aobakeDirectionToBake(reflect(-viewDirectionW, normalW)), roughness)
#endif`,
      '!vec3 finalIrradiance=reflectionOut\\.environmentIrradiance;': `vec3 finalIrradiance=reflectionOut.environmentIrradiance;
#ifdef AOBAKE
#ifdef AOBAKE_VISIBILITY
if (aobakeMode > 1.5) finalIrradiance = aobakeMappedIrradiance(
  aobakeNormalToBake(aobakeVertexNormal(geometricNormalW)), aobakeNormalToBake(normalW));
#else
if (aobakeMode > 1.5) finalIrradiance = aobakeIrradiance();
#endif
#endif`,
      '!finalIrradiance\\*=aoOut\\.ambientOcclusionColor;': `#ifdef AOBAKE
if (aobakeMode > 0.5 && aobakeMode < 1.5) finalIrradiance*=aoOut.ambientOcclusionColor;
#else
finalIrradiance*=aoOut.ambientOcclusionColor;
#endif`,
      '!vec3 finalRadiance=reflectionOut\\.environmentRadiance\\.rgb;': `vec3 finalRadiance=reflectionOut.environmentRadiance.rgb;
#ifdef AOBAKE
if (aobakeMode > 1.5) finalRadiance *= AOBAKE_SPECULAR_OCCLUSION();
#endif`,
      CUSTOM_FRAGMENT_MAIN_END: `#ifdef AOBAKE
if (aobakeDebug > 5.5 && aobakeDebug < 6.5) {
#ifdef REFLECTION
  gl_FragColor = vec4(reflectionOut.environmentIrradiance, 1.0);
#else
  gl_FragColor = vec4(0.0, 0.0, 0.0, 1.0);
#endif
}
else if (aobakeDebug > 9.5) gl_FragColor = vec4(vec3(AOBAKE_SPECULAR_OCCLUSION()), 1.0);
#ifdef AOBAKE_VISIBILITY
else if (aobakeDebug > 6.5) {
  vec3 aobakeN = aobakeNormalToBake(aobakeVertexNormal(geometricNormalW));
  vec3 aobakeNp = aobakeNormalToBake(normalW);
  gl_FragColor = aobakeDebug > 8.5 ? vec4(0.5 + 0.5 * aobakeN, 1.0)
    : aobakeDebug > 7.5 ? vec4(0.5 + 0.5 * aobakeNp, 1.0)
    : vec4(aobakeMappedIrradiance(aobakeN, aobakeNp), 1.0);
}
#endif
else if (aobakeDebug > 4.5) gl_FragColor = vec4(vAobakeUV, aobakeIrradiance().r, aobakePage + 1.0);
else if (aobakeDebug > 3.5) gl_FragColor = vec4(aobakePage, 0.0, 0.0, 1.0);
else if (aobakeDebug > 2.5) gl_FragColor = vec4(vAobakeUV, 0.0, 1.0);
else if (aobakeDebug > 1.5) gl_FragColor = vec4(vec3(aobakeTexel(aobakeAO).r), 1.0);
else if (aobakeDebug > 0.5) gl_FragColor = vec4(aobakeIrradiance(), 1.0);
#endif`,
    };
  }
}
/** The glTF loader extension: binds every baked primitive once the file is loaded. */
class AobakeLightmapExtension {
  constructor(loader, lightmaps) {
    this.name = EXTENSION;
    this.enabled = true;
    this._loader = loader;
    this._lightmaps = lightmaps;
  }

  dispose() {
    this._loader = null;
  }

  async onReady() {
    const loader = this._loader;
    const lm = this._lightmaps;
    const json = loader.gltf;
    const scene = loader.babylonScene;
    lm.clear();
    lm._scene = scene;
    lm.record = json.extensions?.[EXTENSION] ?? null;
    const { filter, problem } = filterOf(lm.record);
    lm.filter = filter;
    if (problem) lm.problems.push(problem);
    const root = loader.rootBabylonMesh;
    if (root) {
      root.computeWorldMatrix(true);
      const m = root.getWorldMatrix().m; // column-major 4x4
      lm.toScene = [m[0], m[4], m[8], m[1], m[5], m[9], m[2], m[6], m[10]];
    }
    const materials = new Map(); // (material, page) -> cloned material
    const textures = new Map(); // texture index -> Babylon texture
    const texture = async (index, context) => {
      if (!textures.has(index)) {
        // nonColorData: linear data, not an sRGB buffer (which the loader
        // otherwise picks, and which the sampler would decode to linear).
        textures.set(index, loader.loadTextureInfoAsync(context, { index, nonColorData: true }, (t) => {
          t.gammaSpace = false;
          t.wrapU = t.wrapV = Texture.CLAMP_ADDRESSMODE;
        }));
      }
      return textures.get(index);
    };
    for (const mesh of scene.meshes) {
      const pointer = (mesh._internalMetadata?.gltf?.pointers ?? []).find((p) => /^\/meshes\/\d+\/primitives\/\d+$/.test(p));
      if (!pointer || mesh.isAnInstance) continue;
      const [mi, pi] = pointer.match(/\d+/g).map(Number);
      const prim = json.meshes?.[mi]?.primitives?.[pi];
      const ext = prim?.extensions?.[EXTENSION];
      if (ext === undefined) continue;
      const label = `meshes[${mi}].primitives[${pi}]`;
      const problem = extensionProblem(ext, json);
      if (problem) {
        lm.problems.push(`${label} ${EXTENSION}: ${problem}`);
        continue;
      }
      const uvName = ext.texCoord === 0 ? 'uv' : `uv${ext.texCoord + 1}`;
      if (!mesh.isVerticesDataPresent(uvName)) {
        lm.problems.push(`${label} ${EXTENSION}: no TEXCOORD_${ext.texCoord}`);
        continue;
      }
      let loaded;
      try {
        const ctx = `${pointer}/extensions/${EXTENSION}`;
        loaded = await Promise.all([
          texture(ext.occlusion.index, `${ctx}/occlusion`),
          ...ext.sh.map((r, i) => texture(r.index, `${ctx}/sh/${i}`)),
          ...(ext.visibility ?? []).map((r, i) => texture(r.index, `${ctx}/visibility/${i}`)),
        ]);
      } catch (e) {
        lm.problems.push(`${label} ${EXTENSION}: a texture does not load (${e.message ?? e})`);
        continue;
      }
      const [occlusion, sh0, sh1, sh2, ...layer] = loaded;
      const sh = [sh0, sh1, sh2];
      const base = mesh.material;
      if (!base) {
        lm.problems.push(`${label} ${EXTENSION}: the primitive has no material to relight`);
        continue;
      }
      const key = `${base.uniqueId}/${ext.page ?? 0}/${ext.texCoord}/${ext.visibility ? 'layer' : ''}`;
      let material = materials.get(key);
      if (!material) {
        material = base.clone(`${base.name} (${EXTENSION} page ${ext.page ?? 0})`);
        // The baked AO on the ambient slot where the material has none.
        if (!material.ambientTexture && 'ambientTexture' in material) {
          material.ambientTexture = occlusion;
          occlusion.coordinatesIndex = ext.texCoord;
          if ('useAmbientInGrayScale' in material) material.useAmbientInGrayScale = true;
        }
        new AobakeLightmapPlugin(material, lm, {
          texCoord: ext.texCoord, occlusion, sh, scale: ext.shScale, offset: ext.shOffset, page: ext.page ?? 0,
          visibility: layer.length > 0 ? layer : null,
          vScale: ext.visibilityScale ?? [], vOffset: ext.visibilityOffset ?? [],
        });
        materials.set(key, material);
      }
      for (const m of [mesh, ...(mesh.instances ?? [])]) m.material = material;
      lm.baked.push({ mesh, label, extension: ext, material, textures: loaded, bump: null });
    }
  }
}

/** Registers the loader extension; every glTF loaded afterwards is bound to `lightmaps`. */
export function registerAobakeLightmap(lightmaps) {
  registerGLTFExtension(EXTENSION, false, (loader) => new AobakeLightmapExtension(loader, lightmaps));
}
