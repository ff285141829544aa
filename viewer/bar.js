// The viewer's page chrome, the same for every engine (viewer.js for
// three.js, babylon-viewer.js for Babylon.js, compare.js for both side by
// side): the bar's controls, the message line, the engine switch, file
// drops, and the `window.aobakeViewer` calls that tests and the side-by-side
// page use. No engine import.
//
// In: an engine's hooks { load(source, name), environment(), mode(),
// normalMaps(), render() } and its AobakeLightmaps (baked, problems,
// record). Out: the bar wired to `state`, and helpers to report status.

import { BUILT_IN, equirect, project } from './environments.js';

const messageBox = document.getElementById('message');
const envSelect = document.getElementById('env');
const rotationInput = document.getElementById('rotation');
const engineSelect = document.getElementById('engine');
const lightingSelect = document.getElementById('lighting');
const params = new URLSearchParams(location.search);

/** The engine this page shows: 'three', 'babylon' or 'both'. */
export const engine = params.get('engine') ?? 'three';
/** The model named by the URL (?model=...), if any. */
export const initialModel = params.get('model');
/** Inside the side-by-side page: no bar of its own. */
export const embedded = params.get('embedded') === '1';
if (embedded) document.getElementById('bar').style.display = 'none';

/** What the bar shows and every engine reads. */
export const state = {
  env: 'sky', rotation: 0, lighting: params.get('lighting') === 'environment' ? 'environment' : 'probe', mode: 'sh', normalMaps: true, image: null, name: '', coefficients: null,
};

export function say(text, level = 'info') {
  messageBox.textContent = text;
  messageBox.className = level;
}

/** The environment's radiance in the file's frame, rotated as chosen: a
 * function of (x, y, z), and its SH (9 x RGB). */
export function environment() {
  const base = state.env === 'image' && state.image
    ? state.image
    : (BUILT_IN[state.env] ?? BUILT_IN.sky).radiance;
  const [c, s] = [Math.cos((state.rotation * Math.PI) / 180), Math.sin((state.rotation * Math.PI) / 180)];
  // The environment rotated by R about +Y is L(R^-1 w) (as `project` does).
  const radiance = (x, y, z) => base(c * x - s * z, y, s * x + c * z);
  const coefficients = project(base, (state.rotation * Math.PI) / 180);
  state.coefficients = coefficients;
  return { radiance, coefficients };
}

/** The message for a loaded file. */
export function describe(lightmaps) {
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

export function status(lightmaps) {
  return {
    message: messageBox.textContent,
    level: messageBox.className,
    baked: lightmaps.baked.length,
    problems: lightmaps.problems.slice(),
    coefficients: state.coefficients,
  };
}

/** Decodes an equirectangular image file into a radiance function. */
async function imageRadiance(file) {
  const bitmap = await createImageBitmap(file, { colorSpaceConversion: 'none' });
  const c = new OffscreenCanvas(bitmap.width, bitmap.height);
  const ctx = c.getContext('2d');
  ctx.drawImage(bitmap, 0, 0);
  return equirect(ctx.getImageData(0, 0, bitmap.width, bitmap.height).data, bitmap.width, bitmap.height);
}

/**
 * Wires the bar to `hooks`: { load(ArrayBuffer, name), environment(),
 * mode(), normalMaps(), lighting() (absent where the engine lights with
 * its environment map alone) }; returns the `window.aobakeViewer` calls
 * they imply (setEnvironment, setMode, setNormalMaps, loadBytes, and with
 * `lighting` setLighting).
 */
export function wireBar(hooks, stage) {
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
  if (hooks.lighting) {
    lightingSelect.value = state.lighting;
    lightingSelect.addEventListener('change', () => {
      state.lighting = lightingSelect.value;
      hooks.lighting();
    });
  } else {
    lightingSelect.value = 'environment';
    lightingSelect.disabled = true;
  }
  envSelect.addEventListener('change', () => {
    state.env = envSelect.value;
    hooks.environment();
  });
  rotationInput.addEventListener('input', () => {
    state.rotation = Number(rotationInput.value);
    document.getElementById('rotationValue').textContent = `${state.rotation}°`;
    hooks.environment();
  });
  for (const radio of document.querySelectorAll('input[name=mode]')) {
    radio.addEventListener('change', () => {
      state.mode = radio.value;
      hooks.mode();
    });
  }
  document.getElementById('normalmaps').addEventListener('change', (e) => {
    state.normalMaps = e.target.checked;
    hooks.normalMaps();
  });
  engineSelect.value = engine;
  engineSelect.addEventListener('change', () => {
    const next = new URLSearchParams(location.search);
    next.set('engine', engineSelect.value);
    location.search = next.toString();
  });
  const loadFile = async (file) => {
    if (file) await hooks.load(await file.arrayBuffer(), file.name);
  };
  document.getElementById('file').addEventListener('change', (e) => loadFile(e.target.files[0]));
  document.getElementById('envimage').addEventListener('change', async (e) => {
    const file = e.target.files[0];
    if (!file) return;
    try {
      state.image = await imageRadiance(file);
      state.env = 'image';
      envSelect.value = 'image';
      hooks.environment();
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
    await loadFile(e.dataTransfer.files[0]);
  });
  return {
    loadBytes: (bytes, name) => hooks.load(new Uint8Array(bytes).buffer, name),
    /** A built-in environment (or 'image' with `image` a radiance function);
     * resolves to its SH once the page is lit by it. */
    async setEnvironment(name, rotationDegrees = 0, image = null) {
      state.env = name;
      state.rotation = rotationDegrees;
      if (image) state.image = image;
      envSelect.value = name;
      rotationInput.value = String(rotationDegrees);
      await hooks.environment();
      return state.coefficients;
    },
    setMode(mode) {
      state.mode = mode;
      document.querySelector(`input[name=mode][value=${mode}]`).checked = true;
      hooks.mode();
    },
    setNormalMaps(on) {
      state.normalMaps = on;
      document.getElementById('normalmaps').checked = on;
      hooks.normalMaps();
    },
    ...(hooks.lighting && {
      /** 'probe' (the environment's SH as a LightProbe: diffuse only) or
       * 'environment' (a prefiltered map of its radiance: diffuse and
       * specular); returns it. */
      async setLighting(name) {
        if (name !== 'environment' && name !== 'probe') throw new Error(`unknown lighting ${name}`);
        state.lighting = name;
        lightingSelect.value = name;
        await hooks.lighting();
        return state.lighting;
      },
    }),
  };
}

/**
 * Camera sync for the side-by-side page: listeners get the view
 * ([position, target] in the file's frame) when the user moves the camera,
 * never for a view set through `set` (a renderer that reports its camera
 * a frame later reports that same view, which is recognised and dropped).
 */
export function viewEvents() {
  const listeners = [];
  let quiet = false;
  let last = null;
  const same = (a, b) => a.every((p, i) => p.every((x, k) => Math.abs(x - b[i][k]) <= 1e-6 * (1 + Math.abs(x))));
  return {
    on: (f) => listeners.push(f),
    emit(view) {
      if (quiet || (last && same(view, last))) return;
      last = null;
      for (const f of listeners) f(view);
    },
    /** Applies a view by `apply()` without notifying. */
    set(view, apply) {
      last = view;
      quiet = true;
      try {
        return apply();
      } finally {
        quiet = false;
      }
    },
  };
}

/**
 * Starts an engine's page: sizes and lights it, loads the URL's model and
 * publishes `window.aobakeViewer` (the same calls on every engine's page).
 * `page`: { load, render, resize, environment, mode, lighting?, api } where `api`
 * holds the engine's own calls (view, currentView, onView, probe, size);
 * the bar (wireBar) is wired to those hooks, its drops to `stage`.
 */
export function startPage(name, lightmaps, page, stage) {
  const calls = wireBar({
    load: page.load,
    environment: page.environment,
    mode: page.mode,
    normalMaps: () => {
      lightmaps.setNormalMaps(state.normalMaps);
      page.render();
    },
    lighting: page.lighting,
  }, stage);
  page.resize();
  page.environment();
  page.mode();
  const ready = initialModel
    ? page.load(initialModel, initialModel.split('/').pop())
    : Promise.resolve(status(lightmaps));
  window.aobakeViewer = {
    engine: name,
    ready,
    load: (url) => page.load(url, url.split('/').pop()),
    ...calls,
    setDebug(debug) {
      lightmaps.setDebug(debug);
      page.render();
    },
    /** Per baked primitive: whether it has the visibility layer. */
    layers: () => lightmaps.baked.map((b) => b.extension.visibility !== undefined),
    status: () => status(lightmaps),
    ...page.api,
  };
}
