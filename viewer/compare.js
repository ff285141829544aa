// Both engines side by side (index.html?engine=both): the three.js page on
// the left and the Babylon.js page on the right, each in a frame of the
// same origin without a bar of its own. This page's bar drives both; a
// camera moved in either is moved in the other (views are exchanged in the
// file's frame, so the mirror Babylon's loader puts under the glTF root
// does not matter).

import { initialModel, say, state, wireBar } from './bar.js';

// Babylon.js lights with its environment map (diffuse and specular): the
// three.js half does too unless the URL asks for the probe.
if (new URLSearchParams(location.search).get('lighting') !== 'probe') state.lighting = 'environment';

const stage = document.getElementById('stage');
document.getElementById('view').remove();

function frameFor(engine) {
  const params = new URLSearchParams({ engine, embedded: '1', lighting: state.lighting });
  if (initialModel) params.set('model', initialModel);
  const frame = document.createElement('iframe');
  frame.title = engine;
  frame.src = `index.html?${params}`;
  stage.append(frame);
  return frame;
}

const frames = [frameFor('three'), frameFor('babylon')];

/** Both pages' `aobakeViewer`, once each has loaded its model. */
async function viewers() {
  const found = [];
  for (const f of frames) {
    while (!f.contentWindow?.aobakeViewer) await new Promise((r) => setTimeout(r, 50));
    await f.contentWindow.aobakeViewer.ready;
    found.push(f.contentWindow.aobakeViewer);
  }
  return found;
}

const ready = viewers().then((both) => {
  // Each camera follows the other.
  both[0].onView(([p, t]) => both[1].view(p, t));
  both[1].onView(([p, t]) => both[0].view(p, t));
  return both;
});

async function each(f) {
  const both = await ready;
  return Promise.all(both.map(f));
}

async function load(bytes, name) {
  const results = await each((v) => v.loadBytes(bytes.slice(0), name));
  const s = results[0];
  say(`${s.message} (left: three.js, right: Babylon.js)`, results.some((r) => r.level === 'error') ? 'error' : s.level);
  return results;
}

const calls = wireBar({
  load,
  environment: () => each((v) => v.setEnvironment(state.env, state.rotation, state.image)),
  mode: () => each((v) => v.setMode(state.mode)),
  normalMaps: () => each((v) => v.setNormalMaps(state.normalMaps)),
  // The three.js half; Babylon.js's has one lighting.
  lighting: () => each((v) => v.setLighting?.(state.lighting)),
}, stage);

ready.then(async ([three]) => {
  const s = await three.status();
  say(`${s.message} (left: three.js, right: Babylon.js)`, s.level);
});

/** For tests: the two pages' calls, and this page's bar. */
window.aobakeViewer = { engine: 'both', ready, viewers: ready, ...calls };
