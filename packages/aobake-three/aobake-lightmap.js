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
// Conventions (checked by the repository's viewer/test/viewer.test.mjs):
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
// The visibility layer (`visibility[4|3]`, `visibilityScale`,
// `visibilityOffset`: v_i = Int V H(n.w) Y_i dw, 16 or 9 coefficients), when
// a primitive has it, lets the normal map drive the baked light: per
// environment P_ik = sum_j Gamma_ijk L_j (a 16 x 16 float texture), per pixel
// u = P^T v and E(n')/pi = c.L + E_C(n')/pi - E_C(n)/pi with n the vertex
// normal and n' the normal-mapped one (the README's formula); and, where the
// material has an environment map, its indirect specular is occluded by the
// lobe-filtered visible radiance over an open receiver's (roughness from the
// material). Without the layer, c.L at the vertex normal and, for the
// specular, the cone of the AO around the bent normal from c.
//
// Use:
//   const lightmaps = new AobakeLightmaps();
//   loader.register((parser) => new AobakeLightmapPlugin(parser, lightmaps));
//   const gltf = await loader.loadAsync(url);
//   lightmaps.setEnvironment(lightProbe.sh);  // radiance SH, world space
//   lightmaps.setMode('sh');                  // 'sh' | 'ao' | 'off'
//
// Which light the bake replaces: a material with an environment map
// (scene.environment or its envMap, PMREM-filtered, as MeshStandardMaterial
// uses it) has its environment map's diffuse replaced, so give
// setEnvironment that map's SH (LightProbeGenerator.fromCubeTexture, times
// envMapIntensity); without one, the scene's LightProbe's diffuse is
// replaced (give its sh). A LightProbe beside an environment map keeps
// adding its own unoccluded light.

import {
  ClampToEdgeWrapping,
  DataTexture,
  FloatType,
  LinearFilter,
  LinearMipmapLinearFilter,
  NearestFilter,
  NoColorSpace,
  RGBAFormat,
  Vector3,
} from 'three';
import {
  BICUBIC_GLSL,
  CONE_GLSL,
  EXTENSION,
  VISIBILITY_GLSL,
  extensionProblem,
  filterOf,
  radianceProduct,
} from 'aobake-contract';

export { EXTENSION, extensionProblem, filterOf };

/** Output modes of the patched materials. */
export const MODES = { off: 0, ao: 1, sh: 2 };

/** Debug outputs (written raw, for tests and diagnostics). */
export const DEBUG = {
  // probe: the environment's own unoccluded irradiance over pi, the light
  // the bake replaces (the environment map's, else the LightProbe's).
  none: 0, irradiance: 1, ao: 2, uv: 3, probe: 4,
  // With the layer: the normal-mapped irradiance over pi, and the world
  // normals n' (normal-mapped) and n (vertex), as 0.5 + 0.5 n.
  mapped: 5, shadingNormal: 6, vertexNormal: 7,
  // The factor on the environment map's specular (the layer's, or the
  // cone of the AO without it), for the material's roughness.
  specularOcclusion: 8,
};

export { basis16, gaunt, radianceProduct } from 'aobake-contract';

/**
 * What the plugin found and the uniforms every patched material shares:
 * the environment's SH, the mode and the debug output.
 */
export class AobakeLightmaps {
  constructor() {
    const product = new DataTexture(new Float32Array(16 * 16 * 4), 16, 16, RGBAFormat, FloatType);
    product.magFilter = product.minFilter = NearestFilter;
    product.needsUpdate = true;
    this.uniforms = {
      aobakeEnvSH: { value: Array.from({ length: 9 }, () => new Vector3()) },
      aobakeP: { value: product },
      aobakeMode: { value: MODES.sh },
      aobakeDebug: { value: DEBUG.none },
    };
    /** Baked meshes: { mesh, label, extension, material }. */
    this.baked = [];
    /** One line per primitive whose extension could not be used. */
    this.problems = [];
    /** The root extension (version, method, rays, ...) of the last file. */
    this.record = null;
    /** The lookup the last file's texels are fitted for ('bilinear' or
     * 'bicubic', the root's `filter`), and a test's override of it. */
    this.filter = 'bilinear';
    this._filterOverride = null;
    this._samplingLevel0 = false;
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
    for (const b of this.baked) setLookup(b.material, this.lookup);
  }

  /** Environment radiance SH (a THREE.SphericalHarmonics3, or 9 Vector3). */
  setEnvironment(sh) {
    const c = sh.coefficients ?? sh;
    for (let i = 0; i < 9; i++) this.uniforms.aobakeEnvSH.value[i].copy(c[i]);
    const p = this.uniforms.aobakeP.value;
    p.image.data.set(radianceProduct(c.map((v) => [v.x, v.y, v.z])));
    p.needsUpdate = true;
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

  /** Normal maps on (the materials' own) or off (removed, so the shading
   * normal is the vertex normal and the bake relights it as c.L). */
  setNormalMaps(on) {
    for (const b of this.baked) {
      const m = b.material;
      if (!on && m.normalMap) {
        m.userData.aobakeNormalMap = m.normalMap;
        m.normalMap = null;
      } else if (on && m.userData.aobakeNormalMap) {
        m.normalMap = m.userData.aobakeNormalMap;
        delete m.userData.aobakeNormalMap;
      }
      m.needsUpdate = true;
    }
  }

  /** Forgets the last file. */
  clear() {
    this.baked = [];
    this.problems = [];
    this.record = null;
    this.filter = 'bilinear';
  }
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
    const { filter, problem } = filterOf(lm.record);
    lm.filter = filter;
    if (problem) lm.problems.push(problem);
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
        [ext.occlusion, ...ext.sh, ...(ext.visibility ?? [])].map((ref) =>
          this.parser.getDependency('texture', ref.index)),
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

// Every lightmap texture's value at the fragment, through the lookup the
// file's texels are fitted for (the root's filter).
#ifdef AOBAKE_BICUBIC
#define AOBAKE_FETCH(s, uv) texture2D(s, uv)
${BICUBIC_GLSL}
#define aobakeTexel(s) aobakeBicubic(s, vAobakeUv)
#else
#define aobakeTexel(s) texture2D(s, vAobakeUv)
#endif

// sum_i c_i L_i = (1/pi) Int V max(0, n.w) L(w) dw (the contract's decode).
vec3 aobakeIrradiance() {
  vec4 a = aobakeTexel(aobakeSh0);
  vec4 b = aobakeTexel(aobakeSh1);
  float c8 = aobakeTexel(aobakeSh2).r;
  float ch[9] = float[9](a.r, a.g, a.b, a.a, b.r, b.g, b.b, b.a, c8);
  vec3 result = vec3(0.0);
  for (int i = 0; i < 9; i++) {
    result += (aobakeShScale[i] * ch[i] + aobakeShOffset[i]) * aobakeEnvSH[i];
  }
  return result;
}

#ifdef AOBAKE_VISIBILITY
uniform sampler2D aobakeV0;
uniform sampler2D aobakeV1;
uniform sampler2D aobakeV2;
uniform sampler2D aobakeV3;
uniform float aobakeVScale[16];
uniform float aobakeVOffset[16];
uniform sampler2D aobakeP;
void aobakeLayer(out float v[16]) {
  vec4 t[4] = vec4[4](aobakeTexel(aobakeV0), aobakeTexel(aobakeV1),
                      aobakeTexel(aobakeV2), aobakeTexel(aobakeV3));
  for (int i = 0; i < 16; i++) {
    v[i] = i < AOBAKE_VCOUNT ? aobakeVScale[i] * t[i / 4][i % 4] + aobakeVOffset[i] : 0.0;
  }
}

${VISIBILITY_GLSL}
#else
// Without the layer: the cone of the AO around the bent normal from c
// (the contract's fallback; aobake-glsl.js).
${CONE_GLSL}
float aobakeSpecularOcclusion(vec3 n, vec3 R, float r) {
  vec4 a = aobakeTexel(aobakeSh0);
  vec3 bent = vec3(aobakeShScale[3] * a.a + aobakeShOffset[3],
                   aobakeShScale[1] * a.g + aobakeShOffset[1],
                   aobakeShScale[2] * a.b + aobakeShOffset[2]);
  bent = length(bent) > 1e-6 ? normalize(bent) : n;
  return aobakeConeOcclusion(bent, clamp(aobakeTexel(aobakeAoTex).r, 0.0, 1.0), R, r);
}
#endif
// The specular occlusion at the fragment, from main()'s variables: one
// expression for the render and the debug output. The material's roughness
// (roughnessmap_fragment's), as Babylon.js has it: three's
// material.roughness adds its specular antialiasing.
#define AOBAKE_SPECULAR_OCCLUSION() aobakeSpecularOcclusion(transformNormalByInverseViewMatrix(nonPerturbedNormal, viewMatrix), transformNormalByInverseViewMatrix(reflect(-geometryViewDir, geometryNormal), viewMatrix), roughnessFactor)
`;

/** A patched material samples its lightmaps with `lookup` ('bilinear' or
 * 'bicubic'): the AOBAKE_BICUBIC define. */
function setLookup(material, lookup) {
  const defines = { ...(material.defines ?? {}) };
  if (lookup === 'bicubic') defines.AOBAKE_BICUBIC = '';
  else delete defines.AOBAKE_BICUBIC;
  material.defines = defines;
  material.needsUpdate = true;
}

/** Patches a standard (or physical) material for the bake. */
export function patchMaterial(material, lightmaps, textures, ext) {
  const [ao, sh0, sh1, sh2, ...layer] = textures;
  const own = {
    aobakeAoTex: { value: ao },
    aobakeSh0: { value: sh0 },
    aobakeSh1: { value: sh1 },
    aobakeSh2: { value: sh2 },
    aobakeShScale: { value: ext.shScale.slice() },
    aobakeShOffset: { value: ext.shOffset.slice() },
  };
  const hasLayer = layer.length > 0;
  if (hasLayer) {
    const pad = (a) => [...a, ...new Array(16 - a.length).fill(0)];
    Object.assign(own, {
      aobakeV0: { value: layer[0] },
      aobakeV1: { value: layer[1] },
      aobakeV2: { value: layer[2] },
      // Order 2 has 3 textures; the fourth is never read then.
      aobakeV3: { value: layer[3] ?? layer[2] },
      aobakeVScale: { value: pad(ext.visibilityScale) },
      aobakeVOffset: { value: pad(ext.visibilityOffset) },
    });
    material.defines = {
      ...(material.defines ?? {}),
      AOBAKE_VISIBILITY: '',
      AOBAKE_VCOUNT: String(ext.visibilityScale.length),
    };
  }
  setLookup(material, lightmaps.lookup);
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
// The environment's own unoccluded irradiance at a normal, the light the
// bake replaces, and the sum it is in: the material's environment map's
// (scene.environment or envMap; iblIrradiance, which three's multiple
// scattering also reads), else the LightProbe's, else none.
#if defined( USE_ENVMAP ) && defined( STANDARD ) && defined( ENVMAP_TYPE_PMREM )
#define AOBAKE_ENVIRONMENT(n) getIBLIrradiance(n)
#define AOBAKE_ENVIRONMENT_SUM iblIrradiance
#elif defined( USE_LIGHT_PROBES )
#define AOBAKE_ENVIRONMENT(n) getLightProbeIrradiance(lightProbe, n)
#define AOBAKE_ENVIRONMENT_SUM irradiance
#else
#define AOBAKE_ENVIRONMENT(n) vec3(0.0)
#define AOBAKE_ENVIRONMENT_SUM irradiance
#endif
#if defined( RE_IndirectDiffuse )
  if (aobakeMode == 2) {
    // The bake replaces the environment's unoccluded diffuse light: three's
    // irradiance E is pi times the decoded sum.
#ifdef AOBAKE_VISIBILITY
    // The normal map's n' (geometryNormal) relit against the vertex
    // normal n the bake used (nonPerturbedNormal), both in world space.
    vec3 aobakeE = PI * aobakeMappedIrradiance(
      transformNormalByInverseViewMatrix(nonPerturbedNormal, viewMatrix),
      transformNormalByInverseViewMatrix(geometryNormal, viewMatrix));
#else
    vec3 aobakeE = PI * aobakeIrradiance();
#endif
    // (Under an environment map, a LightProbe still adds as it would.)
    AOBAKE_ENVIRONMENT_SUM += aobakeE - AOBAKE_ENVIRONMENT(geometryNormal);
  }
#endif
#if defined( RE_IndirectSpecular ) && defined( USE_ENVMAP )
  if (aobakeMode == 2) radiance *= AOBAKE_SPECULAR_OCCLUSION();
#endif`,
      )
      .replace(
        '#include <aomap_fragment>',
        /* glsl */ `#include <aomap_fragment>
  if (aobakeMode == 1) {
    reflectedLight.indirectDiffuse *= aobakeTexel(aobakeAoTex).r;
  }`,
      )
      .replace(
        '#include <dithering_fragment>',
        /* glsl */ `#include <dithering_fragment>
  if (aobakeDebug == 1) gl_FragColor = vec4(aobakeIrradiance(), 1.0);
  else if (aobakeDebug == 2) gl_FragColor = vec4(vec3(aobakeTexel(aobakeAoTex).r), 1.0);
  else if (aobakeDebug == 3) gl_FragColor = vec4(vAobakeUv, 0.0, 1.0);
  else if (aobakeDebug == 4) gl_FragColor = vec4(AOBAKE_ENVIRONMENT(geometryNormal) / PI, 1.0);
#ifdef AOBAKE_VISIBILITY
  else if (aobakeDebug == 5) gl_FragColor = vec4(aobakeMappedIrradiance(
    transformNormalByInverseViewMatrix(nonPerturbedNormal, viewMatrix),
    transformNormalByInverseViewMatrix(normal, viewMatrix)), 1.0);
#endif
  else if (aobakeDebug == 8) gl_FragColor = vec4(vec3(AOBAKE_SPECULAR_OCCLUSION()), 1.0);
  else if (aobakeDebug == 6) gl_FragColor = vec4(0.5 + 0.5 * transformNormalByInverseViewMatrix(normal, viewMatrix), 1.0);
  else if (aobakeDebug == 7) gl_FragColor = vec4(0.5 + 0.5 * transformNormalByInverseViewMatrix(nonPerturbedNormal, viewMatrix), 1.0);`,
      );
  };
  material.customProgramCacheKey = () =>
    `aobake-lightmap-v4-${hasLayer ? ext.visibilityScale.length : 0}-${'AOBAKE_BICUBIC' in material.defines ? 'bicubic' : 'bilinear'}`;
  // The material's own occlusionTexture would multiply the indirect light
  // again: the bake's AO is applied by the modes above instead.
  material.aoMapIntensity = 0;
  material.needsUpdate = true;
}
