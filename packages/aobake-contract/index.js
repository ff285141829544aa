// aobake-contract: the engine-neutral part of the AOBAKE_lightmap contract
// (docs/extensions/AOBAKE_lightmap in the aobake repository), shared by the
// engine importers aobake-three and aobake-babylon.
//
// In: nothing (pure modules, no engine import). Out: the extension's name
// and checks (extension.js), the real SH basis, quadrature, Gamma and the
// visibility layer's matrix P (sh.js), and the contract's GLSL formulas
// (glsl.js).

export { EXTENSION, extensionProblem, filterOf } from './extension.js';
export { basis16, basis9, gaunt, project, radianceProduct, sphereRule } from './sh.js';
export { BICUBIC_GLSL, CONE_GLSL, VISIBILITY_GLSL } from './glsl.js';
