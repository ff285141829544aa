// The two engines against each other, as `aobake view` shows them
// (viewer/index.html?engine=three | babylon | both): the same bake, the
// same environment (the viewer's SH, in the file's frame) and the same
// camera, rendered by three.js and Babylon.js in headless Chromium. The
// baked light each engine's shader reconstructs (c.L, the AO, and on the
// normal-mapped helmet the anchored diffuse) is compared pixel by pixel at
// 8 bits; the beauty frames' difference is measured and printed.
//
// Run: npm run test:babylon (after `cargo build --release` and `npm ci` in
// the repository's root); cargo test runs it through tests/babylon.rs.

import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import pngjs from 'pngjs';
import { bake, launch, open, repoDir, serve, tempDir, testAssets } from '../../viewer/test/harness.mjs';
import { readGlb, writeGlb } from '../../viewer/test/decode.mjs';
import { check } from '../build-viewer.mjs';

const dir = tempDir();
const files = {};
let browser;
const VIEWPORT = { width: 640, height: 560 };
const { PNG } = pngjs;

/**
 * The Cornell box with no specular: KHR_materials_specular's factor 0 on
 * every material (F0 = F90 = 0 in both engines). Each engine's frame is
 * then the albedo times the same baked light, with no Fresnel split.
 */
function matteCornell(path) {
  const { json, bin } = readGlb(readFileSync(join(repoDir, 'assets/cornell_box.glb')));
  for (const m of json.materials) m.extensions = { ...m.extensions, KHR_materials_specular: { specularFactor: 0 } };
  json.extensionsUsed = [...new Set([...(json.extensionsUsed ?? []), 'KHR_materials_specular'])];
  writeFileSync(path, writeGlb(json, bin));
  return path;
}

before(async () => {
  files.matte = bake(matteCornell(join(dir, 'matte-in.glb')), join(dir, 'matte.glb'), ['--resolution', '256', '--rays', '64']);
  files.cornell = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'), ['--resolution', '256', '--rays', '64']);
  files.helmet = bake(join(testAssets, 'flight_helmet.glb'), join(dir, 'helmet.glb'), ['--resolution', '512', '--quality', '32']);
  browser = await launch();
});

after(async () => {
  await browser?.close();
});

test('the Babylon.js bundle aobake view serves is what this checkout builds', async () => {
  assert.equal(await check(), null);
});

/** Every `step`-th pixel of the canvas. */
function grid([w, h], step) {
  const out = [];
  for (let y = 0; y < h; y += step) for (let x = 0; x < w; x += step) out.push([x, y]);
  return out;
}

const to8 = (x) => Math.round(255 * Math.min(1, Math.max(0, x)));

/**
 * The mean |three - Babylon| (in 8-bit steps, over RGB) of debug output
 * `debug` over the pixels both engines cover with a baked primitive, and
 * the share of those pixels that differ by more than 2 steps.
 */
async function compare(pages, debug, pixels) {
  const [a, b] = await Promise.all(pages.map((p) => p.evaluate(([d, px]) => window.aobakeViewer.probe(d, px), [debug, pixels])));
  let n = 0;
  let sum = 0;
  let over = 0;
  let onlyOne = 0;
  for (let k = 0; k < pixels.length; k++) {
    // Covered: alpha 1, or more where Babylon adds the alpha of a blended
    // material's layers (its colour is the top layer's, as three's).
    const [ca, cb] = [a[k][3] >= 1, b[k][3] >= 1];
    if (ca !== cb) {
      onlyOne++;
      if (process.env.AOBAKE_DEBUG) console.log('# only', ca ? 'three' : 'babylon', pixels[k], JSON.stringify(a[k]), JSON.stringify(b[k]));
    }
    if (!ca || !cb) continue;
    let d = 0;
    for (let c = 0; c < 3; c++) d += Math.abs(to8(a[k][c]) - to8(b[k][c]));
    sum += d / 3;
    if (d / 3 > 2) over++;
    n++;
  }
  return { n, mean: sum / Math.max(1, n), over: over / Math.max(1, n), onlyOne, mask: a.map((p, k) => p[3] >= 1 && b[k][3] >= 1) };
}

/** Both canvases as decoded 8-bit sRGB PNGs ([three, Babylon]). */
async function frames(pages) {
  // A software renderer can take long to draw a frame on a loaded machine.
  return Promise.all(pages.map(async (p) => PNG.sync.read(await p.locator('#view').screenshot({ timeout: 300000 }))));
}

/**
 * Mean over the pixels of `mask` and the RGB channels of |d(o)|, in 8-bit
 * steps, where d(o) is a difference of the frames' bytes at offset o.
 */
function meanOver(pixels, mask, width, d) {
  let n = 0;
  let sum = 0;
  for (let k = 0; k < pixels.length; k++) {
    if (!mask[k]) continue;
    const [x, y] = pixels[k];
    const o = (y * width + x) * 4;
    for (let c = 0; c < 3; c++) sum += Math.abs(d(o + c)) / 3;
    n++;
  }
  return sum / Math.max(1, n);
}

/**
 * The beauty frames of both engines with the baked light ('sh') and
 * without it ('off'), on the pixels of `mask`: |three - Babylon| with the
 * bake, and the same without it (each engine's own shading of the
 * environment, diffuse included, which the importers do not touch).
 */
async function beauty(pages, pixels, mask) {
  const [w3, wb] = await frames(pages);
  for (const p of pages) await p.evaluate(() => window.aobakeViewer.setMode('off'));
  const [o3, ob] = await frames(pages);
  for (const p of pages) await p.evaluate(() => window.aobakeViewer.setMode('sh'));
  const at = (d) => meanOver(pixels, mask, w3.width, d);
  return {
    baked: at((o) => w3.data[o] - wb.data[o]),
    engines: at((o) => o3.data[o] - ob.data[o]),
  };
}

/**
 * The same bake in both engines: the debug outputs `debugs` compared pixel
 * by pixel (asserted), then the beauty frames measured; with `beautyBound`
 * their difference with the baked light is asserted below it.
 */
async function sameBakeTwoEngines(name, debugs, beautyBound = null) {
  const server = await serve(files[name]);
  try {
    const pages = [];
    for (const engine of ['three', 'babylon']) pages.push(await open(browser, `${server.url}&engine=${engine}`, VIEWPORT));
    for (const p of pages) assert.deepEqual((await p.evaluate(() => window.aobakeViewer.status())).problems, []);
    const sizes = await Promise.all(pages.map((p) => p.evaluate(() => window.aobakeViewer.size())));
    assert.deepEqual(sizes[0], sizes[1]);
    // The same environment's SH in both (the viewer's projection).
    const L = await Promise.all(pages.map((p) => p.evaluate(() => window.aobakeViewer.setEnvironment('sky'))));
    assert.deepEqual(L[0], L[1]);
    // Babylon's camera where three's is (both frame the model alike; this
    // makes it exact).
    const view = await pages[0].evaluate(() => window.aobakeViewer.currentView());
    await pages[1].evaluate((v) => window.aobakeViewer.view(...v), view);
    const pixels = grid(sizes[0], 2);
    const results = {};
    for (const debug of debugs) {
      const r = await compare(pages, debug, pixels);
      console.log(`# ${name} ${debug}: ${r.n} pixels on baked surfaces in both; mean |three - Babylon| = ${r.mean.toFixed(3)}/255, ${(100 * r.over).toFixed(2)}% of pixels over 2/255; ${r.onlyOne} pixels covered in one engine only`);
      assert.ok(r.n > 2000, `${name} ${debug}: ${r.n} pixels`);
      assert.ok(r.mean < 2, `${name} ${debug}: mean ${r.mean}/255`);
      assert.ok(r.onlyOne < 0.02 * r.n, `${name} ${debug}: ${r.onlyOne} pixels covered by one engine only (the views differ)`);
      results[debug] = r;
    }
    // Measured and printed, not asserted (the engines' BRDFs differ). The
    // three.js page lit by an environment map of the same radiance, as
    // Babylon's is (diffuse and specular); then the same frames without the
    // baked light: how far apart the engines are on their own.
    await pages[0].evaluate(() => window.aobakeViewer.setLighting('environment'));
    const b = await beauty(pages, pixels, results[debugs[0]].mask).catch((e) => {
      console.log(`# ${name} beauty frames not measured: ${e.message.split('\n')[0]}`);
      return null;
    });
    if (b) {
      console.log(`# ${name} beauty frames (sky, both lit by the environment's map), mean |three - Babylon| on baked surfaces: with the baked light ${b.baked.toFixed(2)}/255; without it (each engine's own diffuse and specular light) ${b.engines.toFixed(2)}/255`);
      // The importers replace each engine's diffuse light and occlude its
      // specular with the same bake and formulas: they bring the engines
      // closer, never further apart than their own shading of the map (up
      // to half a step: the frames read the lightmaps through each
      // engine's own mip selection, the debug outputs at level 0).
      assert.ok(b.baked <= b.engines + 0.5, `${name}: the baked frames differ by ${b.baked}/255, more than the engines alone (${b.engines}/255)`);
    }
    if (beautyBound !== null) {
      assert.ok(b, `${name}: the beauty frames were not measured`);
      assert.ok(b.baked < beautyBound, `${name}: the baked frames differ by ${b.baked}/255 (bound ${beautyBound}/255)`);
    }
    for (const p of pages) {
      assert.deepEqual(p.errors, []);
      await p.close();
    }
  } finally {
    server.stop();
  }
}

test('Cornell box: three.js and Babylon.js reconstruct the same baked light', async () => {
  await sameBakeTwoEngines('cornell', ['irradiance', 'ao', 'specularOcclusion']);
});

test('a Cornell box without specular: the two engines\' relit frames agree within 2/255', async () => {
  await sameBakeTwoEngines('matte', ['irradiance'], 2);
});

test('flight helmet: the same normal-mapped baked light in both engines', async () => {
  await sameBakeTwoEngines('helmet', ['irradiance', 'mapped', 'specularOcclusion']);
});

test('side by side: both engines load the file, and the camera moved in one moves the other', async () => {
  const server = await serve(files.cornell);
  try {
    const page = await open(browser, `${server.url}&engine=both`, { width: 1000, height: 560 });
    const frames = page.frames().filter((f) => f !== page.mainFrame());
    assert.equal(frames.length, 2);
    const engines = await Promise.all(frames.map((f) => f.evaluate(() => window.aobakeViewer.engine)));
    assert.deepEqual([...engines].sort(), ['babylon', 'three']);
    const of = (engine) => frames[engines.indexOf(engine)];
    for (const f of frames) {
      const s = await f.evaluate(() => window.aobakeViewer.status());
      assert.ok(s.baked > 0 && s.problems.length === 0, s.message);
    }
    const message = await page.evaluate(() => document.getElementById('message').textContent);
    assert.match(message, /baked primitive.*three\.js.*Babylon\.js/);
    // Both halves lit by the environment's map (Babylon.js has no other
    // lighting), and the bar switches the three.js half to the probe.
    const lighting = () => Promise.all(['three', 'babylon'].map((e) => of(e).evaluate(() => document.getElementById('lighting').value)));
    assert.deepEqual(await lighting(), ['environment', 'environment']);
    assert.equal(await page.evaluate(() => window.aobakeViewer.setLighting('probe')), 'probe');
    assert.deepEqual(await lighting(), ['probe', 'environment']);
    // The bar drives both pages.
    await page.evaluate(() => window.aobakeViewer.setEnvironment('sunset', 90));
    const L = await Promise.all(frames.map((f) => f.evaluate(() => window.aobakeViewer.status().coefficients)));
    assert.deepEqual(L[0], L[1]);
    // Drag in each half: the other camera follows.
    // three.js on the left, Babylon.js on the right.
    for (const [x0, from, to] of [[250, 'three', 'babylon'], [750, 'babylon', 'three']]) {
      const before = await of(to).evaluate(() => window.aobakeViewer.currentView());
      await page.mouse.move(x0, 330);
      await page.mouse.down();
      for (let k = 1; k <= 10; k++) await page.mouse.move(x0 + 8 * k, 330 + 3 * k);
      await page.mouse.up();
      // Babylon applies input at its next frames (with inertia).
      await new Promise((r) => setTimeout(r, 1500));
      const moved = await of(from).evaluate(() => window.aobakeViewer.currentView());
      const followed = await of(to).evaluate(() => window.aobakeViewer.currentView());
      const dist = (a, b) => Math.hypot(...a.map((x, i) => x - b[i]));
      const scale = dist(moved[0], moved[1]);
      console.log(`# drag in ${from}: camera moved ${dist(before[0], followed[0]).toFixed(3)}, the two cameras ${dist(moved[0], followed[0]).toExponential(2)} apart (view distance ${scale.toFixed(2)})`);
      assert.ok(dist(before[0], followed[0]) > 0.01 * scale, 'the drag moved the cameras');
      assert.ok(dist(moved[0], followed[0]) < 1e-4 * scale, 'the other camera followed');
      assert.ok(dist(moved[1], followed[1]) < 1e-4 * scale, 'the targets agree');
    }
    assert.deepEqual(page.errors, []);
    await page.close();
  } finally {
    server.stop();
  }
});
