// The viewer page: opens a baked GLB (URL, file picker or drop; nothing is
// uploaded), lights it with an SH environment through a LightProbe and the
// AOBAKE_lightmap plugin, and exposes `window.aobakeViewer` for tests.

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { AobakeLightmapPlugin, AobakeLightmaps } from './aobake-lightmap.js';
import { BUILT_IN, equirect, project } from './environments.js';

const canvas = document.getElementById('view');
const stage = document.getElementById('stage');
const messageBox = document.getElementById('message');
const envSelect = document.getElementById('env');
const rotationInput = document.getElementById('rotation');

const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.outputColorSpace = THREE.SRGBColorSpace;
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x303134);
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 1000);
const controls = new OrbitControls(camera, canvas);
const probe = new THREE.LightProbe();
scene.add(probe);
const lightmaps = new AobakeLightmaps();

const state = {
  env: 'sky', rotation: 0, mode: 'sh', normalMaps: true, image: null, model: null, name: '',
};

function say(text, level = 'info') {
  messageBox.textContent = text;
  messageBox.className = level;
}

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

/** The environment's SH (9 x RGB) for the current choice and rotation. */
function environmentSH() {
  const radiance = state.env === 'image' && state.image
    ? state.image
    : (BUILT_IN[state.env] ?? BUILT_IN.sky).radiance;
  return project(radiance, (state.rotation * Math.PI) / 180);
}

function applyEnvironment() {
  const coeffs = environmentSH();
  for (let i = 0; i < 9; i++) probe.sh.coefficients[i].fromArray(coeffs[i]);
  lightmaps.setEnvironment(probe.sh);
  state.coefficients = coeffs;
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
  controls.update();
}

function describe() {
  const n = lightmaps.baked.length;
  const problems = lightmaps.problems;
  const name = state.name || 'the file';
  if (problems.length > 0) {
    const shown = problems.slice(0, 5).join('\n');
    const more = problems.length > 5 ? `\n(${problems.length - 5} more)` : '';
    return [`${name}: AOBAKE_lightmap is malformed, these primitives render without the bake:\n${shown}${more}`, 'error'];
  }
  if (n === 0) {
    return [`${name} has no AOBAKE_lightmap: shown with the environment's light only (bake it with aobake first).`, 'warn'];
  }
  const r = lightmaps.record;
  const how = r ? ` (${r.method}, ${r.rays} rays, ${r.resolution?.join('x')} atlas)` : '';
  return [`${name}: ${n} baked primitive${n === 1 ? '' : 's'}${how}.`, 'info'];
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
  if (state.model) scene.remove(state.model);
  state.model = gltf.scene;
  state.name = name;
  scene.add(gltf.scene);
  frame(gltf.scene);
  if (!state.normalMaps) lightmaps.setNormalMaps(false);
  applyEnvironment();
  applyMode();
  say(...describe());
  render();
  return status();
}

function status() {
  return {
    message: messageBox.textContent,
    level: messageBox.className,
    baked: lightmaps.baked.length,
    problems: lightmaps.problems.slice(),
    coefficients: state.coefficients,
  };
}

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
  render();
  return pixels.map(([x, y]) => {
    const o = ((h - 1 - y) * w + x) * 4;
    return [data[o], data[o + 1], data[o + 2], data[o + 3]];
  });
}

// UI.
for (const [key, env] of Object.entries(BUILT_IN)) {
  const option = document.createElement('option');
  option.value = key;
  option.textContent = env.label;
  envSelect.append(option);
}
const imageOption = document.createElement('option');
imageOption.value = 'image';
imageOption.textContent = 'image (choose one)';
envSelect.append(imageOption);
envSelect.value = state.env;
envSelect.addEventListener('change', () => {
  state.env = envSelect.value;
  applyEnvironment();
});
rotationInput.addEventListener('input', () => {
  state.rotation = Number(rotationInput.value);
  document.getElementById('rotationValue').textContent = `${state.rotation}°`;
  applyEnvironment();
});
for (const radio of document.querySelectorAll('input[name=mode]')) {
  radio.addEventListener('change', () => {
    state.mode = radio.value;
    applyMode();
  });
}
document.getElementById('normalmaps').addEventListener('change', (e) => {
  state.normalMaps = e.target.checked;
  lightmaps.setNormalMaps(state.normalMaps);
  render();
});
document.getElementById('file').addEventListener('change', async (e) => {
  const file = e.target.files[0];
  if (file) await load(await file.arrayBuffer(), file.name);
});
document.getElementById('envimage').addEventListener('change', async (e) => {
  const file = e.target.files[0];
  if (!file) return;
  try {
    const bitmap = await createImageBitmap(file, { colorSpaceConversion: 'none' });
    const c = new OffscreenCanvas(bitmap.width, bitmap.height);
    const ctx = c.getContext('2d');
    ctx.drawImage(bitmap, 0, 0);
    const pixels = ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
    state.image = equirect(pixels, bitmap.width, bitmap.height);
    state.env = 'image';
    envSelect.value = 'image';
    applyEnvironment();
  } catch (err) {
    say(`${file.name} is not an image this browser decodes: ${err.message ?? err}`, 'error');
  }
});
stage.addEventListener('dragover', (e) => {
  e.preventDefault();
  stage.classList.add('dragging');
});
stage.addEventListener('dragleave', () => stage.classList.remove('dragging'));
stage.addEventListener('drop', async (e) => {
  e.preventDefault();
  stage.classList.remove('dragging');
  const file = e.dataTransfer.files[0];
  if (file) await load(await file.arrayBuffer(), file.name);
});
controls.addEventListener('change', render);
window.addEventListener('resize', () => {
  resize();
  render();
});

resize();
applyEnvironment();
applyMode();

const params = new URLSearchParams(location.search);
const initial = params.get('model');
const ready = initial ? load(initial, initial.split('/').pop()) : Promise.resolve(status());

/** For tests and scripts. */
window.aobakeViewer = {
  ready,
  load: (url) => load(url, url.split('/').pop()),
  loadBytes: (bytes, name) => load(new Uint8Array(bytes).buffer, name),
  setEnvironment(name, rotationDegrees = 0) {
    state.env = name;
    state.rotation = rotationDegrees;
    envSelect.value = name;
    rotationInput.value = String(rotationDegrees);
    applyEnvironment();
    return state.coefficients;
  },
  setMode(mode) {
    state.mode = mode;
    document.querySelector(`input[name=mode][value=${mode}]`).checked = true;
    applyMode();
  },
  setNormalMaps(on) {
    state.normalMaps = on;
    document.getElementById('normalmaps').checked = on;
    lightmaps.setNormalMaps(on);
    render();
  },
  setDebug(name) {
    lightmaps.setDebug(name);
    render();
  },
  /** Per baked primitive: whether it has the visibility layer. */
  layers: () => lightmaps.baked.map((b) => b.extension.visibility !== undefined),
  view(position, target) {
    camera.position.fromArray(position);
    controls.target.fromArray(target);
    controls.update();
    render();
  },
  probe: probePixels,
  status,
  size: () => [canvas.width, canvas.height],
};
