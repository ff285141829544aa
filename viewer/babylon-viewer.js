// The viewer page in Babylon.js (index.html?engine=babylon): the same bar,
// environments and `window.aobakeViewer` calls as the three.js page
// (viewer.js), with the package aobake-babylon as the importer. Babylon.js
// and the importer come as one bundle (vendor/babylon/aobake-babylon.js,
// built by babylon/build-viewer.mjs).
//
// The baked light uses the environment's SH exactly as the three.js page
// does (environments.js's projection, in the file's frame); the scene's
// own environment (unbaked surfaces, specular) is a 32-pixel half-float
// cube of the same radiance taken through the loader's root (a mirror),
// prefiltered by Babylon's HDRFiltering as its .env files are.

import {
  AobakeLightmaps, ArcRotateCamera, Color4, Constants, CubeMapToSphericalPolynomialTools, Engine,
  HDRFiltering, RawCubeTexture, Scene, SceneLoader, ToHalfFloat, Vector3, registerAobakeLightmap, toBakeRows,
} from './vendor/babylon/aobake-babylon.js';
import {
  describe, environment, say, startPage, state, status as barStatus, viewEvents,
} from './bar.js';

const canvas = document.getElementById('view');
const stage = document.getElementById('stage');
SceneLoader.ShowLoadingScreen = false;
const engine = new Engine(canvas, true, { preserveDrawingBuffer: true, stencil: false });
const scene = new Scene(engine);
scene.clearColor = new Color4(0x30 / 255, 0x31 / 255, 0x34 / 255, 1);
scene.imageProcessingConfiguration.toneMappingEnabled = false;
const camera = new ArcRotateCamera('camera', -Math.PI / 2, Math.PI / 2.5, 3, Vector3.Zero(), scene);
camera.fov = (45 * Math.PI) / 180;
camera.attachControl(canvas, true);
camera.wheelDeltaPercentage = 0.01;
const lightmaps = new AobakeLightmaps();
registerAobakeLightmap(lightmaps);
const views = viewEvents();
let cube = null;

/** Row-major 3x3 times a vector. */
const apply = (m, p) => [0, 1, 2].map((r) => m[3 * r] * p[0] + m[3 * r + 1] * p[1] + m[3 * r + 2] * p[2]);
/** The file's frame to Babylon's world and back (points and directions). */
const toScene = (p) => new Vector3(...apply(lightmaps.toScene, p));
const toFile = (v) => toBakeRows(lightmaps.toScene).direction.map((row) => row[0] * v.x + row[1] * v.y + row[2] * v.z);

/** Cube faces in GL order: +X, -X, +Y, -Y, +Z, -Z (normal, s, t axes). */
const FACES = [
  ['right', [1, 0, 0], [0, 0, -1], [0, -1, 0]], ['left', [-1, 0, 0], [0, 0, 1], [0, -1, 0]],
  ['up', [0, 1, 0], [1, 0, 0], [0, 0, 1]], ['down', [0, -1, 0], [1, 0, 0], [0, 0, -1]],
  ['front', [0, 0, 1], [1, 0, 0], [0, -1, 0]], ['back', [0, 0, -1], [-1, 0, 0], [0, -1, 0]],
];

/** The scene's environment cube of `radiance` (a function of the file's
 * frame), with the spherical polynomial Babylon's own tool makes of it. */
function environmentCube(radiance, size = 32) {
  const info = { size, format: Constants.TEXTUREFORMAT_RGBA, type: Constants.TEXTURETYPE_FLOAT, gammaSpace: false };
  const faces = [];
  for (const [name, n, fs, ft] of FACES) {
    const data = new Float32Array(size * size * 4);
    for (let y = 0; y < size; y++) {
      for (let x = 0; x < size; x++) {
        const s = ((x + 0.5) / size) * 2 - 1;
        const t = ((y + 0.5) / size) * 2 - 1;
        const d = [0, 1, 2].map((k) => n[k] + s * fs[k] + t * ft[k]);
        const w = toFile({ x: d[0], y: d[1], z: d[2] });
        const len = Math.hypot(...w);
        const c = radiance(w[0] / len, w[1] / len, w[2] / len);
        data.set([c[0], c[1], c[2], 1], (y * size + x) * 4);
      }
    }
    info[name] = data;
    faces.push(data);
  }
  // Half floats: float textures need not filter in WebGL2 (SwiftShader's
  // do not), and a cube without filtered mips gives every roughness the
  // sharp radiance.
  const halves = faces.map((f) => Uint16Array.from(f, ToHalfFloat));
  const texture = new RawCubeTexture(scene, halves, size, Constants.TEXTUREFORMAT_RGBA, Constants.TEXTURETYPE_HALF_FLOAT, true);
  texture.sphericalPolynomial = CubeMapToSphericalPolynomialTools.ConvertCubeMapToSphericalPolynomial(info);
  return texture;
}

function resize() {
  engine.resize();
}

let dirty = true;
/** Asks for a frame: drawn by the loop, only when something changed (a
 * software renderer keeps up with two pages side by side this way). */
function render() {
  dirty = true;
}

/** Whether the camera is still moving (inertia, or input not yet applied). */
const moving = () => camera.inertialAlphaOffset !== 0 || camera.inertialBetaOffset !== 0
  || camera.inertialRadiusOffset !== 0 || camera.inertialPanningX !== 0 || camera.inertialPanningY !== 0;

let generation = 0;
/** Lights the scene with the bar's environment; resolves once its cube is
 * prefiltered and in place (a later call supersedes an earlier one). */
async function applyEnvironment() {
  const { radiance, coefficients } = environment();
  lightmaps.setEnvironment(coefficients);
  const mine = ++generation;
  const next = environmentCube(radiance);
  // Babylon's own GGX prefilter (as for its .env and .hdr files): mip k
  // holds the radiance for roughness k of the PBR's LOD mapping. Where it
  // cannot run (WebGL1), the cube's own mips light the specular.
  try {
    await new HDRFiltering(engine, { quality: Constants.TEXTURE_FILTERING_QUALITY_OFFLINE }).prefilter(next);
  } catch (e) {
    console.warn(`the environment's specular is not prefiltered: ${e.message ?? e}`);
  }
  if (mine !== generation) {
    next.dispose();
    return;
  }
  scene.environmentTexture = next;
  cube?.dispose();
  cube = next;
  render();
}

function applyMode() {
  lightmaps.setMode(state.mode);
  render();
}

/** The three.js page's first view: from the front, a little above. */
function frame() {
  const { min, max } = scene.getWorldExtends((m) => m.isVisible && m.getTotalVertices() > 0);
  const size = max.subtract(min).length() || 1;
  const centre = toFile(min.add(max).scale(0.5));
  camera.minZ = size / 1000;
  camera.maxZ = size * 100;
  view([centre[0], centre[1] + size * 0.05, centre[2] + size * 0.9], centre);
}

function view(position, target) {
  views.set([position, target], () => {
    camera.setTarget(toScene(target));
    camera.setPosition(toScene(position));
  });
  render();
}

async function load(source, name) {
  say(`loading ${name} ...`);
  for (const m of [...scene.meshes]) m.dispose(false, true);
  try {
    if (typeof source === 'string') await SceneLoader.AppendAsync(source, undefined, scene, undefined, '.glb');
    else await SceneLoader.AppendAsync('', new Uint8Array(source), scene, undefined, '.glb');
  } catch (e) {
    say(`${name} does not load: ${e.message ?? e}`, 'error');
    render();
    return status();
  }
  state.name = name;
  frame();
  if (!state.normalMaps) lightmaps.setNormalMaps(false);
  await applyEnvironment();
  applyMode();
  await new Promise((ok) => scene.executeWhenReady(ok));
  say(...describe(lightmaps));
  render();
  return status();
}

const status = () => barStatus(lightmaps);

/** [r, g, b, a] of a float render of the baked meshes with debug output
 * `debug` at each pixel [x, y]; a = 0 off them (the importer's probe). */
async function probePixels(debug, pixels) {
  // The probe draws into its own target and restores what it changed: the
  // canvas's frame stands (another frame of a large model takes a
  // software rasterizer seconds).
  return lightmaps.probe(scene, camera, debug, pixels, [engine.getRenderWidth(), engine.getRenderHeight()]);
}

camera.onViewMatrixChangedObservable.add(() => {
  render();
  views.emit([toFile(camera.position), toFile(camera.target)]);
});
window.addEventListener('resize', () => {
  resize();
  render();
});
engine.runRenderLoop(() => {
  if (!dirty && !moving()) return;
  dirty = false;
  scene.render();
});

startPage('babylon', lightmaps, {
  load, render, resize, environment: applyEnvironment, mode: applyMode,
  api: {
    view,
    /** [position, target] of the camera, in the file's frame. */
    currentView: () => [toFile(camera.position), toFile(camera.target)],
    onView: views.on,
    probe: probePixels,
    size: () => [engine.getRenderWidth(), engine.getRenderHeight()],
    /** The loader root's linear part (row-major): the file's frame to Babylon's. */
    toScene: () => lightmaps.toScene,
  },
}, stage);
