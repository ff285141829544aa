// three.js GLTFLoader plugin for aobake's `AOBAKE_lightmap` extension.
//
// In: a glTF written by aobake (the contract in aobake's README: per baked
// primitive `extensions.AOBAKE_lightmap = {texCoord, occlusion, sh[3],
// shScale[9], shOffset[9]}`), and the SH coefficients of an environment's
// radiance. Out: each baked mesh's standard material patched so that its
// diffuse indirect light is albedo x sum_i c_i L_i, with
// c_i = shScale[i] * channel_i + shOffset[i] read from the three SH
// textures on the extension's UV set.
//
// Conventions (checked by viewer/test/viewer.test.mjs):
// - basis and order: the contract's real SH, (l,m) = (0,0),(1,-1),(1,0),(1,1),
//   (2,-2),(2,-1),(2,0),(2,1),(2,2), no Condon-Shortley phase, is the basis
//   and order of three's SphericalHarmonics3 (getBasisAt) and LightProbe:
//   an environment's coefficients L_i go in unchanged;
// - scale: c_i already carries the 1/pi, so sum_i c_i L_i = E / pi, where
//   three's irradiance E (shGetIrradianceAt) is what its Lambert BRDF divides
//   by pi; the patch adds pi * sum_i c_i L_i to `irradiance`, so an open
//   receiver relights exactly as three's own LightProbe does;
// - world space: the bake's directions are the file's world axes, which
//   GLTFLoader keeps (Y up);
// - channels: c0..c3 = sh[0].rgba, c4..c7 = sh[1].rgba, c8 = sh[2].r; the
//   alpha channels hold data, which GLTFLoader's ImageBitmapLoader keeps
//   (premultiplyAlpha 'none', colorSpaceConversion 'none');
// - colour space: the textures hold linear data (NoColorSpace), clamp to
//   edge, UVs as stored (GLTFLoader's flipY = false, v = 0 at the top).
//
// Use:
//   const lightmaps = new AobakeLightmaps();
//   loader.register((parser) => new AobakeLightmapPlugin(parser, lightmaps));
//   const gltf = await loader.loadAsync(url);
//   lightmaps.setEnvironment(lightProbe.sh);  // radiance SH, world space
//   lightmaps.setMode('sh');                  // 'sh' | 'ao' | 'off'

import {
  ClampToEdgeWrapping,
  LinearFilter,
  LinearMipmapLinearFilter,
  NoColorSpace,
  Vector3,
} from 'three';

export const EXTENSION = 'AOBAKE_lightmap';

/** Output modes of the patched materials. */
export const MODES = { off: 0, ao: 1, sh: 2 };

/** Debug outputs (written raw, for tests and diagnostics). */
export const DEBUG = { none: 0, irradiance: 1, ao: 2, uv: 3, probe: 4 };

/**
 * What the plugin found and the uniforms every patched material shares:
 * the environment's SH, the mode and the debug output.
 */
export class AobakeLightmaps {
  constructor() {
    this.uniforms = {
      aobakeEnvSH: { value: Array.from({ length: 9 }, () => new Vector3()) },
      aobakeMode: { value: MODES.sh },
      aobakeDebug: { value: DEBUG.none },
    };
    /** Baked meshes: { mesh, label, extension, material }. */
    this.baked = [];
    /** One line per primitive whose extension could not be used. */
    this.problems = [];
    /** The root extension (version, method, rays, ...) of the last file. */
    this.record = null;
    this._samplingLevel0 = false;
  }

  /** Environment radiance SH (a THREE.SphericalHarmonics3, or 9 Vector3). */
  setEnvironment(sh) {
    const c = sh.coefficients ?? sh;
    for (let i = 0; i < 9; i++) this.uniforms.aobakeEnvSH.value[i].copy(c[i]);
  }

  /** 'sh': relight with the SH; 'ao': the environment's own light times the
   * baked AO; 'off': no baked light. */
  setMode(mode) {
    if (!(mode in MODES)) throw new Error(`unknown mode ${mode}`);
    this.uniforms.aobakeMode.value = MODES[mode];
  }

  /** Debug output of every patched material ('none' for normal shading). */
  setDebug(name) {
    if (!(name in DEBUG)) throw new Error(`unknown debug output ${name}`);
    this.uniforms.aobakeDebug.value = DEBUG[name];
  }

  /** Sample the lightmaps at mip level 0 (bilinear), as a CPU decoder
   * does: for probe renders that compare with decoded textures. */
  setLevel0(on) {
    this._samplingLevel0 = on;
    for (const b of this.baked) {
      for (const t of b.textures) {
        t.minFilter = on ? LinearFilter : LinearMipmapLinearFilter;
        t.needsUpdate = true;
      }
    }
  }

  /** Forgets the last file. */
  clear() {
    this.baked = [];
    this.problems = [];
    this.record = null;
  }
}

/** Why an extension object cannot be used, or null. */
export function extensionProblem(ext, json) {
  if (typeof ext !== 'object' || ext === null) return 'is not an object';
  const textures = json.textures ?? [];
  const texture = (ref, what) => {
    if (typeof ref !== 'object' || ref === null || !Number.isInteger(ref.index)) {
      return `${what} has no texture index`;
    }
    if (ref.index < 0 || ref.index >= textures.length) {
      return `${what} names textures[${ref.index}], which does not exist`;
    }
    return null;
  };
  if (!Number.isInteger(ext.texCoord) || ext.texCoord < 0) return 'texCoord is not a set index';
  const occ = texture(ext.occlusion, 'occlusion');
  if (occ) return occ;
  if (!Array.isArray(ext.sh) || ext.sh.length !== 3) return 'sh must list 3 textures';
  for (let i = 0; i < 3; i++) {
    const p = texture(ext.sh[i], `sh[${i}]`);
    if (p) return p;
  }
  for (const key of ['shScale', 'shOffset']) {
    const v = ext[key];
    if (!Array.isArray(v) || v.length !== 9) {
      return `${key} must hold 9 numbers (has ${Array.isArray(v) ? v.length : 'none'})`;
    }
    if (!v.every((x) => typeof x === 'number' && Number.isFinite(x))) {
      return `${key} holds a value that is not a finite number`;
    }
  }
  return null;
}

/** GLTFLoader attribute name of TEXCOORD_n. */
function uvAttribute(n) {
  return n === 0 ? 'uv' : `uv${n}`;
}

/** The GLTFLoader plugin: `loader.register((p) => new AobakeLightmapPlugin(p, lightmaps))`. */
export class AobakeLightmapPlugin {
  constructor(parser, lightmaps) {
    this.parser = parser;
    this.name = EXTENSION;
    this.lightmaps = lightmaps;
  }

  async afterRoot(gltf) {
    const json = this.parser.json;
    const lm = this.lightmaps;
    lm.clear();
    lm.record = json.extensions?.[EXTENSION] ?? null;
    const jobs = [];
    gltf.scene.traverse((obj) => {
      if (!obj.isMesh) return;
      const ref = this.parser.associations.get(obj);
      if (!ref || ref.meshes === undefined || ref.primitives === undefined) return;
      const prim = json.meshes?.[ref.meshes]?.primitives?.[ref.primitives];
      const ext = prim?.extensions?.[EXTENSION];
      if (ext === undefined) return;
      const label = `meshes[${ref.meshes}].primitives[${ref.primitives}]`;
      jobs.push(this._bind(obj, ext, label, json));
    });
    await Promise.all(jobs);
    gltf.userData.aobake = { baked: lm.baked.length, problems: lm.problems, record: lm.record };
  }

  async _bind(mesh, ext, label, json) {
    const lm = this.lightmaps;
    const problem = extensionProblem(ext, json);
    if (problem) {
      lm.problems.push(`${label} ${EXTENSION}: ${problem}`);
      return;
    }
    const uv = mesh.geometry.getAttribute(uvAttribute(ext.texCoord));
    if (!uv) {
      lm.problems.push(`${label} ${EXTENSION}: no TEXCOORD_${ext.texCoord}`);
      return;
    }
    let textures;
    try {
      textures = await Promise.all(
        [ext.occlusion, ...ext.sh].map((ref) => this.parser.getDependency('texture', ref.index)),
      );
    } catch (e) {
      lm.problems.push(`${label} ${EXTENSION}: a texture does not load (${e.message ?? e})`);
      return;
    }
    textures = textures.map((t) => {
      // Our own copies: the contract's sampler and linear data, whatever the
      // file's other uses of the image say.
      const c = t.clone();
      c.colorSpace = NoColorSpace;
      c.wrapS = c.wrapT = ClampToEdgeWrapping;
      c.magFilter = LinearFilter;
      c.minFilter = lm._samplingLevel0 ? LinearFilter : LinearMipmapLinearFilter;
      c.needsUpdate = true;
      return c;
    });
    mesh.geometry.setAttribute('aobakeUv', uv);
    const material = mesh.material.clone();
    patchMaterial(material, lm, textures, ext);
    mesh.material = material;
    lm.baked.push({ mesh, label, extension: ext, material, textures });
  }
}

const VERTEX_DECL = /* glsl */ `
attribute vec2 aobakeUv;
varying vec2 vAobakeUv;
`;

const FRAGMENT_DECL = /* glsl */ `
varying vec2 vAobakeUv;
uniform sampler2D aobakeAoTex;
uniform sampler2D aobakeSh0;
uniform sampler2D aobakeSh1;
uniform sampler2D aobakeSh2;
uniform float aobakeShScale[9];
uniform float aobakeShOffset[9];
uniform vec3 aobakeEnvSH[9];
uniform int aobakeMode;
uniform int aobakeDebug;

// sum_i c_i L_i = (1/pi) Int V max(0, n.w) L(w) dw (the contract's decode).
vec3 aobakeIrradiance() {
  vec4 a = texture2D(aobakeSh0, vAobakeUv);
  vec4 b = texture2D(aobakeSh1, vAobakeUv);
  float c8 = texture2D(aobakeSh2, vAobakeUv).r;
  float ch[9] = float[9](a.r, a.g, a.b, a.a, b.r, b.g, b.b, b.a, c8);
  vec3 result = vec3(0.0);
  for (int i = 0; i < 9; i++) {
    result += (aobakeShScale[i] * ch[i] + aobakeShOffset[i]) * aobakeEnvSH[i];
  }
  return result;
}
`;

/** Patches a standard (or physical) material for the bake. */
export function patchMaterial(material, lightmaps, textures, ext) {
  const [ao, sh0, sh1, sh2] = textures;
  const own = {
    aobakeAoTex: { value: ao },
    aobakeSh0: { value: sh0 },
    aobakeSh1: { value: sh1 },
    aobakeSh2: { value: sh2 },
    aobakeShScale: { value: ext.shScale.slice() },
    aobakeShOffset: { value: ext.shOffset.slice() },
  };
  material.userData.aobake = own;
  material.onBeforeCompile = (shader) => {
    Object.assign(shader.uniforms, own, lightmaps.uniforms);
    shader.vertexShader = VERTEX_DECL + shader.vertexShader.replace(
      '#include <uv_vertex>',
      '#include <uv_vertex>\n\tvAobakeUv = aobakeUv;',
    );
    shader.fragmentShader = FRAGMENT_DECL + shader.fragmentShader
      .replace(
        '#include <lights_fragment_maps>',
        /* glsl */ `#include <lights_fragment_maps>
#if defined( RE_IndirectDiffuse )
  if (aobakeMode == 2) {
    // The bake replaces the probe's unoccluded light: three's irradiance E
    // is pi times the decoded sum.
    irradiance -= getLightProbeIrradiance(lightProbe, geometryNormal);
    irradiance += PI * aobakeIrradiance();
  }
#endif`,
      )
      .replace(
        '#include <aomap_fragment>',
        /* glsl */ `#include <aomap_fragment>
  if (aobakeMode == 1) {
    reflectedLight.indirectDiffuse *= texture2D(aobakeAoTex, vAobakeUv).r;
  }`,
      )
      .replace(
        '#include <dithering_fragment>',
        /* glsl */ `#include <dithering_fragment>
  if (aobakeDebug == 1) gl_FragColor = vec4(aobakeIrradiance(), 1.0);
  else if (aobakeDebug == 2) gl_FragColor = vec4(vec3(texture2D(aobakeAoTex, vAobakeUv).r), 1.0);
  else if (aobakeDebug == 3) gl_FragColor = vec4(vAobakeUv, 0.0, 1.0);
  else if (aobakeDebug == 4) gl_FragColor = vec4(getLightProbeIrradiance(lightProbe, geometryNormal) / PI, 1.0);`,
      );
  };
  material.customProgramCacheKey = () => 'aobake-lightmap-v1';
  // The material's own occlusionTexture would multiply the indirect light
  // again: the bake's AO is applied by the modes above instead.
  material.aoMapIntensity = 0;
  material.needsUpdate = true;
}
