// The GLSL of the bake in Babylon.js's PBR fragment shader (the contract's
// formulas, as the aobake-three plugin has them for three.js).
//
// In (declared by the plugin in aobake-lightmap.js): the layer's textures
// aobakeV0..3 with ranges aobakeVScale0..3 / aobakeVOffset0..3,
// AOBAKE_VCOUNT (16 or 9), P in aobakeP (16 x 16 float), the c textures
// aobakeSH0..2 with aobakeScale0..2 / aobakeOffset0..2 and the AO in
// aobakeAO, aobakeTexel(), aobakeIrradiance() (c.L), and the rows taking
// Babylon-world normals and directions into the bake's frame. Out:
// aobakeNormalToBake, aobakeDirectionToBake; with the layer (LAYER_GLSL)
// its v_i at the fragment and the shared formulas
// (aobake-contract's glsl.js: aobakeMappedIrradiance,
// aobakeSpecularOcclusion); without it (FALLBACK_GLSL) the contract's
// fallback specular occlusion, the cone of the AO around the bent normal
// (aobakeSpecularOcclusion with the same arguments).
import { CONE_GLSL, VISIBILITY_GLSL } from 'aobake-contract';

export const FRAME_GLSL = `
// Babylon-world normal and direction into the bake's frame.
vec3 aobakeNormalToBake(vec3 n) {
  return normalize(vec3(dot(aobakeNormalRow0, n), dot(aobakeNormalRow1, n), dot(aobakeNormalRow2, n)));
}
vec3 aobakeDirectionToBake(vec3 d) {
  return normalize(vec3(dot(aobakeDirectionRow0, d), dot(aobakeDirectionRow1, d), dot(aobakeDirectionRow2, d)));
}`;

export const LAYER_GLSL = `
void aobakeLayer(out float v[16]) {
  vec4 t[4] = vec4[4](aobakeTexel(aobakeV0), aobakeTexel(aobakeV1), aobakeTexel(aobakeV2), aobakeTexel(aobakeV3));
  vec4 sc[4] = vec4[4](aobakeVScale0, aobakeVScale1, aobakeVScale2, aobakeVScale3);
  vec4 of[4] = vec4[4](aobakeVOffset0, aobakeVOffset1, aobakeVOffset2, aobakeVOffset3);
  for (int i = 0; i < 16; i++) {
    v[i] = i < AOBAKE_VCOUNT ? sc[i / 4][i % 4] * t[i / 4][i % 4] + of[i / 4][i % 4] : 0.0;
  }
}
${VISIBILITY_GLSL}`;

export const FALLBACK_GLSL = `
${CONE_GLSL}
float aobakeSpecularOcclusion(vec3 n, vec3 R, float r) {
  vec4 a = aobakeTexel(aobakeSH0) * aobakeScale0 + aobakeOffset0;
  vec3 bent = vec3(a.w, a.y, a.z);
  bent = length(bent) > 1e-6 ? normalize(bent) : n;
  return aobakeConeOcclusion(bent, clamp(aobakeTexel(aobakeAO).r, 0.0, 1.0), R, r);
}`;
