// The visibility layer's GLSL, the same in both engine importers
// (the packages aobake-three and aobake-babylon):
// the contract's formulas for the normal-mapped diffuse and the specular
// occlusion. No engine import.
//
// In (declared by the importer before this chunk): AOBAKE_VCOUNT (16 or
// 9), the 16 x 16 float texture aobakeP (P_ik = sum_j Gamma_ijk L_j, row i,
// column k), aobakeLayer(out float v[16]) (the layer's v_i at the
// fragment) and aobakeIrradiance() (c.L). Out: aobakeMappedIrradiance(n,
// n') and aobakeSpecularOcclusion(n, R, roughness), all vectors in the
// bake's frame. CONE_GLSL, for primitives without the layer: the
// contract's fallback specular occlusion from the AO and the bent normal.

export const VISIBILITY_GLSL = /* glsl */ `
const int AOBAKE_BAND[16] = int[16](0, 1, 1, 1, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3);

void aobakeBasis(vec3 w, out float y[16]) {
  float x = w.x, yy = w.y, z = w.z;
  y[0] = 0.282095; y[1] = 0.488603 * yy; y[2] = 0.488603 * z; y[3] = 0.488603 * x;
  y[4] = 1.092548 * x * yy; y[5] = 1.092548 * yy * z; y[6] = 0.315392 * (3.0 * z * z - 1.0);
  y[7] = 1.092548 * x * z; y[8] = 0.546274 * (x * x - yy * yy);
  y[9] = 0.590044 * yy * (3.0 * x * x - yy * yy); y[10] = 2.890611 * x * yy * z;
  y[11] = 0.457046 * yy * (5.0 * z * z - 1.0); y[12] = 0.373176 * z * (5.0 * z * z - 3.0);
  y[13] = 0.457046 * x * (5.0 * z * z - 1.0); y[14] = 1.445306 * z * (x * x - yy * yy);
  y[15] = 0.590044 * x * (x * x - 3.0 * yy * yy);
}

// u = P^T v: the visible radiance's projection (v from the layer, or any
// 16 coefficients, e.g. an open receiver's).
void aobakeVisibleRadiance(float v[16], out vec3 u[16]) {
  for (int k = 0; k < 16; k++) u[k] = vec3(0.0);
  for (int i = 0; i < AOBAKE_VCOUNT; i++) {
    for (int k = 0; k < 16; k++) u[k] += v[i] * texelFetch(aobakeP, ivec2(k, i), 0).rgb;
  }
}

// E_C(m) / pi = (1/pi) sum_{k<9} A_l u_k Y_k(m).
vec3 aobakeIrradianceAt(vec3 u[16], vec3 m) {
  float y[16];
  aobakeBasis(m, y);
  const float A[3] = float[3](3.14159265, 2.09439510, 0.78539816);
  vec3 e = vec3(0.0);
  for (int k = 0; k < 9; k++) e += A[AOBAKE_BAND[k]] * u[k] * y[k];
  return e / 3.14159265;
}

// The anchored diffuse over pi at the world shading normal np, for the
// world vertex normal n: c.L + E_C(np)/pi - E_C(n)/pi.
vec3 aobakeMappedIrradiance(vec3 n, vec3 np) {
  float v[16];
  vec3 u[16];
  aobakeLayer(v);
  aobakeVisibleRadiance(v, u);
  return aobakeIrradiance() + aobakeIrradianceAt(u, np) - aobakeIrradianceAt(u, n);
}

// Specular occlusion of a lobe of perceptual roughness r about the world
// direction R: the lobe-filtered visible radiance over an open receiver's
// (zonal factors exp(-l^2 / (2 s)) of a Phong lobe, s = 2 / alpha^2 - 2).
float aobakeSpecularOcclusion(vec3 n, vec3 R, float r) {
  float v[16], open[16], y[16];
  vec3 u[16], uo[16];
  aobakeLayer(v);
  aobakeBasis(n, y);
  const float lambda[4] = float[4](6.28318531, 3.14159265, 0.0, -0.78539816);
  for (int i = 0; i < 16; i++) open[i] = lambda[AOBAKE_BAND[i]] * y[i];
  aobakeVisibleRadiance(v, u);
  aobakeVisibleRadiance(open, uo);
  aobakeBasis(R, y);
  float a = max(r * r, 1e-3), s = max(2.0 / (a * a) - 2.0, 1e-3);
  vec3 seen = vec3(0.0), unoccluded = vec3(0.0);
  for (int k = 0; k < 16; k++) {
    float l = float(AOBAKE_BAND[k]);
    float w = exp(-l * l / (2.0 * s)) * y[k];
    seen += w * u[k];
    unoccluded += w * uo[k];
  }
  const vec3 lum = vec3(0.2126, 0.7152, 0.0722);
  float o = dot(unoccluded, lum);
  return o > 1e-6 ? clamp(dot(seen, lum) / o, 0.0, 1.0) : 1.0;
}
`;

// Without the layer (the contract's fallback, Jimenez et al. 2016): a
// visibility cone of cos = sqrt(1 - AO) around the bent normal (c_3, c_1,
// c_2) and the glossy lobe's cone around R (half-angle roughness^2 pi/2),
// their overlap by a smooth step of the angle between them. In: the bent
// normal (unit), the AO, R and the roughness; out: the specular's factor.
export const CONE_GLSL = /* glsl */ `
float aobakeConeOcclusion(vec3 bent, float ao, vec3 R, float r) {
  float cosVis = sqrt(max(1.0 - ao, 0.0));
  float cosLobe = cos(clamp(r * r, 0.02, 1.0) * 1.5707963);
  float rv = acos(clamp(cosVis, -1.0, 1.0)), rl = acos(clamp(cosLobe, -1.0, 1.0));
  float d = acos(clamp(dot(bent, R), -1.0, 1.0));
  float overlap = 1.0 - smoothstep(0.0, 1.0, (d - abs(rv - rl)) / max(rv + rl - abs(rv - rl), 1e-4));
  float full = (1.0 - cosVis) / max(1.0 - cosLobe, 1e-4);
  return clamp(mix(0.0, min(full, 1.0), overlap), 0.0, 1.0);
}
`;

// The contract's bicubic lookup (`"filter": "bicubic"` in the root's
// AOBAKE_lightmap): the uniform cubic B-spline over 4 x 4 texels, clamp to
// edge, as four bilinear fetches (Sigg and Hadwiger, GPU Gems 2, ch. 20:
// per axis the taps' weights pair up as g0 = w0 + w1 at a point between
// taps 0 and 1, g1 = w2 + w3 between 2 and 3). In (declared before this
// chunk): AOBAKE_FETCH(s, uv), the importer's bilinear fetch. Out:
// aobakeBicubic(s, uv).
export const BICUBIC_GLSL = /* glsl */ `
vec4 aobakeBicubic(sampler2D s, vec2 uv) {
  vec2 size = vec2(textureSize(s, 0));
  vec2 x = uv * size - 0.5;
  vec2 i = floor(x);
  vec2 f = x - i;
  vec2 g = 1.0 - f;
  vec2 w0 = g * g * g / 6.0;
  vec2 w1 = (3.0 * f * f * f - 6.0 * f * f + 4.0) / 6.0;
  vec2 w2 = (-3.0 * f * f * f + 3.0 * f * f + 3.0 * f + 1.0) / 6.0;
  vec2 w3 = f * f * f / 6.0;
  vec2 g0 = w0 + w1;
  vec2 g1 = w2 + w3;
  // Fetch points in texel-centre units (i - 1 + w1 / g0 lies between taps
  // i - 1 and i), back to UV.
  vec2 h0 = (i - 1.0 + w1 / g0 + 0.5) / size;
  vec2 h1 = (i + 1.0 + w3 / g1 + 0.5) / size;
  return g0.y * (g0.x * AOBAKE_FETCH(s, vec2(h0.x, h0.y)) + g1.x * AOBAKE_FETCH(s, vec2(h1.x, h0.y)))
       + g1.y * (g0.x * AOBAKE_FETCH(s, vec2(h0.x, h1.y)) + g1.x * AOBAKE_FETCH(s, vec2(h1.x, h1.y)));
}`;
