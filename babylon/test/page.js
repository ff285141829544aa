// The Babylon.js side of babylon/test/babylon.test.mjs: loads an aobake GLB
// with the importer, sets environments made of a radiance function (turned
// into Babylon's spherical polynomial by Babylon's own cube-map tool), and
// reads pixels of a float render target.

import '@babylonjs/core/index.js';
import '@babylonjs/loaders/glTF/2.0/index.js';
import { Engine } from '@babylonjs/core/Engines/engine.js';
import { Scene } from '@babylonjs/core/scene.js';
import { ArcRotateCamera } from '@babylonjs/core/Cameras/arcRotateCamera.js';
import { Vector3 } from '@babylonjs/core/Maths/math.vector.js';
import { Color4 } from '@babylonjs/core/Maths/math.color.js';
import { RawCubeTexture } from '@babylonjs/core/Materials/Textures/rawCubeTexture.js';
import { CubeMapToSphericalPolynomialTools } from '@babylonjs/core/Misc/HighDynamicRange/cubemapToSphericalPolynomial.js';
import { SceneLoader } from '@babylonjs/core/Loading/sceneLoader.js';
import { Constants } from '@babylonjs/core/Engines/constants.js';
import { AobakeLightmaps, registerAobakeLightmap } from 'aobake-babylon';

const canvas = document.getElementById('view');
const engine = new Engine(canvas, false, { preserveDrawingBuffer: true, stencil: false });
const scene = new Scene(engine);
scene.clearColor = new Color4(0, 0, 0, 0);
scene.imageProcessingConfiguration.isEnabled = false;
const camera = new ArcRotateCamera('camera', -Math.PI / 2, Math.PI / 2.5, 3, Vector3.Zero(), scene);
const lightmaps = new AobakeLightmaps();
registerAobakeLightmap(lightmaps);

/** Environments as radiance functions of a Babylon-world direction. */
const lobe = (d) => (w) => { const c = 3 * Math.max(0, w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) ** 4; return [c, c, c]; };
const ENVIRONMENTS = {
  white: () => [1, 1, 1],
  'lobe+x': lobe([1, 0, 0]), 'lobe-x': lobe([-1, 0, 0]),
  'lobe+y': lobe([0, 1, 0]), 'lobe-y': lobe([0, -1, 0]),
  'lobe+z': lobe([0, 0, 1]),
  sky: (w) => [0.3 + 0.7 * Math.max(0, w[1]), 0.4 + 0.6 * Math.max(0, w[1]), 0.6 + 0.4 * Math.max(0, w[1]) + 0.2 * w[0]],
};

/** Babylon's spherical polynomial of `f`, by its own cube-map projection. */
function polynomialOf(f, size = 32) {
  const faces = [
    ['right', [1, 0, 0], [0, 0, -1], [0, -1, 0]], ['left', [-1, 0, 0], [0, 0, 1], [0, -1, 0]],
    ['up', [0, 1, 0], [1, 0, 0], [0, 0, 1]], ['down', [0, -1, 0], [1, 0, 0], [0, 0, -1]],
    ['front', [0, 0, 1], [1, 0, 0], [0, -1, 0]], ['back', [0, 0, -1], [-1, 0, 0], [0, -1, 0]],
  ];
  const info = { size, format: Constants.TEXTUREFORMAT_RGBA, type: Constants.TEXTURETYPE_FLOAT, gammaSpace: false };
  for (const [name, n, fx, fy] of faces) {
    const data = new Float32Array(size * size * 4);
    for (let y = 0; y < size; y++) {
      for (let x = 0; x < size; x++) {
        const u = ((x + 0.5) / size) * 2 - 1;
        const v = ((y + 0.5) / size) * 2 - 1;
        const d = [0, 1, 2].map((k) => n[k] + u * fx[k] + v * fy[k]);
        const len = Math.hypot(...d);
        const c = f(d.map((e) => e / len));
        data.set([c[0], c[1], c[2], 1], (y * size + x) * 4);
      }
    }
    info[name] = data;
  }
  return CubeMapToSphericalPolynomialTools.ConvertCubeMapToSphericalPolynomial(info);
}

// A black environment cube (no specular light) whose polynomial is set per environment.
const black = new Uint8Array(4);
const env = new RawCubeTexture(scene, [black, black, black, black, black, black], 1);
scene.environmentTexture = env;

window.aobakeBabylon = {
  ready: Promise.resolve(true),
  async load(url) {
    for (const m of [...scene.meshes]) m.dispose(false, true);
    await SceneLoader.AppendAsync(url, undefined, scene, undefined, '.glb');
    const { min, max } = scene.getWorldExtends((m) => m.isVisible && m.getTotalVertices() > 0);
    const centre = min.add(max).scale(0.5);
    camera.setTarget(centre);
    camera.radius = max.subtract(min).length() * 0.9;
    camera.minZ = camera.radius * 0.01;
    camera.maxZ = camera.radius * 10;
    return { baked: lightmaps.baked.length, problems: lightmaps.problems, record: lightmaps.record };
  },
  /** Sets a named environment; returns the importer's L_i (bake frame). */
  setEnvironment(name) {
    env.sphericalPolynomial = polynomialOf(ENVIRONMENTS[name]);
    scene.resetCachedMaterial();
    return lightmaps.setEnvironmentFromScene(scene);
  },
  toScene: () => lightmaps.toScene,
  /** Per baked primitive: whether it has the visibility layer. */
  layers: () => lightmaps.baked.map((b) => b.extension.visibility !== undefined),
  setNormalMaps: (on) => lightmaps.setNormalMaps(on),
  /** The camera at `position` looking at `target`, both in the file's
   * (glTF) frame, taken through the loader's root. */
  lookAt(position, target) {
    const m = lightmaps.toScene;
    const map = (p) => new Vector3(...[0, 1, 2].map((r) => m[3 * r] * p[0] + m[3 * r + 1] * p[1] + m[3 * r + 2] * p[2]));
    camera.setPosition(map(position));
    camera.setTarget(map(target));
  },
  setMode: (m) => lightmaps.setMode(m),
  /** Sample with 'bilinear' or 'bicubic' whatever the file says (null: as it says). */
  setFilter: (f) => lightmaps.setFilter(f),
  /** Camera angles, and optionally its distance as a share of the view's. */
  view(alpha, beta, radius) {
    camera.alpha = alpha;
    camera.beta = beta;
    if (radius) camera.radius *= radius / 0.9;
  },
  size: () => [engine.getRenderWidth(), engine.getRenderHeight()],
  /** [r, g, b, a] at each pixel [x, y] (from the top left) of a float
   * render of the baked meshes with debug output `debug`; a = 0 off them. */
  probe(debug, pixels) {
    return lightmaps.probe(scene, camera, debug, pixels, this.size());
  },
  /** The canvas as rendered (8-bit), for screenshots. */
  async render() {
    await new Promise((ok) => scene.executeWhenReady(ok));
    scene.render();
    scene.render();
  },
};
engine.runRenderLoop(() => {});

