// The viewer page in three.js: opens a baked GLB (URL, file picker or drop;
// nothing is uploaded), lights it with an environment (a LightProbe of its
// SH, the default; or, with the bar's lighting 'environment' or
// setLighting('environment'), a PMREM-filtered map of its radiance as
// scene.environment: diffuse and specular, like the Babylon.js page's
// cube) and the AOBAKE_lightmap plugin, and exposes
// `window.aobakeViewer` (bar.js's startPage) for tests and the side-by-side
// page. The bar and its state are bar.js's (shared with the Babylon.js
// page).

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { AobakeLightmapPlugin, AobakeLightmaps } from 'aobake-three';
import {
  describe, environment, say, startPage, state, status as barStatus, viewEvents,
} from './bar.js';

const canvas = document.getElementById('view');
const stage = document.getElementById('stage');

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.outputColorSpace = THREE.SRGBColorSpace;
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x303134);
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 1000);
const controls = new OrbitControls(camera, canvas);
// The environment's SH (given to the plugin either way), and the probe
// that lights with it in 'probe' lighting (the bar's state.lighting).
const probe = new THREE.LightProbe();
const pmrem = new THREE.PMREMGenerator(renderer);
let environmentTarget = null;
const lightmaps = new AobakeLightmaps();
const views = viewEvents();
let model = null;

function resize() {
  const w = stage.clientWidth;
  const h = stage.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / Math.max(1, h);
  camera.updateProjectionMatrix();
}

function render() {
  renderer.render(scene, camera);
}

/** A PMREM of `radiance` (a function of the world direction): an
 * equirectangular float image in three's layout (u = atan2(z, x) / 2 pi +
 * 1/2, v = asin(y) / pi + 1/2, row 0 at v = 0). */
function environmentMap(radiance, width = 128, height = 64) {
  // Half floats: linear filtering of float textures is optional in WebGL2
  // (SwiftShader has none), and the PMREM filters the image linearly.
  const data = new Uint16Array(width * height * 4);
  const half = THREE.DataUtils.toHalfFloat;
  for (let y = 0; y < height; y++) {
    const lat = ((y + 0.5) / height - 0.5) * Math.PI;
    for (let x = 0; x < width; x++) {
      const phi = ((x + 0.5) / width - 0.5) * 2 * Math.PI;
      const c = radiance(Math.cos(phi) * Math.cos(lat), Math.sin(lat), Math.sin(phi) * Math.cos(lat));
      data.set([half(c[0]), half(c[1]), half(c[2]), half(1)], (y * width + x) * 4);
    }
  }
  const image = new THREE.DataTexture(data, width, height, THREE.RGBAFormat, THREE.HalfFloatType);
  image.mapping = THREE.EquirectangularReflectionMapping;
  image.colorSpace = THREE.LinearSRGBColorSpace;
  image.magFilter = THREE.LinearFilter;
  image.needsUpdate = true;
  const target = pmrem.fromEquirectangular(image);
  image.dispose();
  return target;
}

function applyEnvironment() {
  const { radiance, coefficients } = environment();
  for (let i = 0; i < 9; i++) probe.sh.coefficients[i].fromArray(coefficients[i]);
  lightmaps.setEnvironment(probe.sh);
  environmentTarget?.dispose();
  environmentTarget = null;
  scene.environment = null;
  scene.remove(probe);
  if (state.lighting === 'environment') {
    environmentTarget = environmentMap(radiance);
    scene.environment = environmentTarget.texture;
  } else {
    scene.add(probe);
  }
  render();
}

function applyMode() {
  lightmaps.setMode(state.mode);
  render();
}

function frame(object) {
  const box = new THREE.Box3().setFromObject(object);
  const size = box.getSize(new THREE.Vector3()).length() || 1;
  const centre = box.getCenter(new THREE.Vector3());
  controls.target.copy(centre);
  camera.near = size / 1000;
  camera.far = size * 100;
  camera.position.copy(centre).add(new THREE.Vector3(0, size * 0.05, size * 0.9));
  camera.updateProjectionMatrix();
  views.set([camera.position.toArray(), controls.target.toArray()], () => controls.update());
}

/** Loads a GLB from an ArrayBuffer or a URL; resolves to the status. */
async function load(source, name) {
  const loader = new GLTFLoader();
  loader.register((parser) => new AobakeLightmapPlugin(parser, lightmaps));
  say(`loading ${name} ...`);
  let gltf;
  try {
    gltf = typeof source === 'string'
      ? await loader.loadAsync(source)
      : await loader.parseAsync(source, '');
  } catch (e) {
    say(`${name} does not load: ${e.message ?? e}`, 'error');
    render();
    return status();
  }
  if (model) scene.remove(model);
  model = gltf.scene;
  state.name = name;
  scene.add(gltf.scene);
  frame(gltf.scene);
  if (!state.normalMaps) lightmaps.setNormalMaps(false);
  applyEnvironment();
  applyMode();
  say(...describe(lightmaps));
  render();
  return status();
}

const status = () => barStatus(lightmaps);

/**
 * Renders one frame with a debug output into a float target (raw shader
 * values, no colour conversion, lightmaps sampled at level 0) and returns
 * [r, g, b, a] at each pixel [x, y] (from the top left); a = 0 where no
 * baked primitive is.
 */
function probePixels(debug, pixels) {
  const w = canvas.width;
  const h = canvas.height;
  const target = new THREE.WebGLRenderTarget(w, h, { type: THREE.FloatType });
  const hidden = [];
  scene.traverse((o) => {
    if (o.isMesh && o.visible && !lightmaps.baked.some((b) => b.mesh === o)) {
      o.visible = false;
      hidden.push(o);
    }
  });
  const background = scene.background;
  scene.background = null;
  lightmaps.setLevel0(true);
  lightmaps.setDebug(debug);
  renderer.setRenderTarget(target);
  renderer.setClearColor(0x000000, 0);
  renderer.clear();
  renderer.render(scene, camera);
  const data = new Float32Array(w * h * 4);
  renderer.readRenderTargetPixels(target, 0, 0, w, h, data);
  renderer.setRenderTarget(null);
  lightmaps.setDebug('none');
  lightmaps.setLevel0(false);
  scene.background = background;
  for (const o of hidden) o.visible = true;
  target.dispose();
  // The canvas's frame stands: the probe drew into its own target and
  // restored what it changed.
  return pixels.map(([x, y]) => {
    const o = ((h - 1 - y) * w + x) * 4;
    return [data[o], data[o + 1], data[o + 2], data[o + 3]];
  });
}

controls.addEventListener('change', () => {
  render();
  views.emit([camera.position.toArray(), controls.target.toArray()]);
});
window.addEventListener('resize', () => {
  resize();
  render();
});

startPage('three', lightmaps, {
  load, render, resize, environment: applyEnvironment, mode: applyMode, lighting: applyEnvironment,
  api: {
    /** The camera at `position` looking at `target`, in the file's frame. */
    view(position, target) {
      camera.position.fromArray(position);
      controls.target.fromArray(target);
      views.set([position, target], () => controls.update());
      render();
    },
    /** [position, target] of the camera, in the file's frame. */
    currentView: () => [camera.position.toArray(), controls.target.toArray()],
    /** Called with [position, target] when the user moves the camera. */
    onView: views.on,
    probe: probePixels,
    /** Sample with 'bilinear' or 'bicubic' whatever the file says (null:
     * as it says). */
    setFilter(name) {
      lightmaps.setFilter(name);
      render();
    },
    size: () => [canvas.width, canvas.height],
  },
}, stage);
