// The viewer and the AOBAKE_lightmap plugin in a real browser (Debian's
// Chromium, headless, software WebGL), against expectations computed here
// from the decoded textures, independently of the shader.
//
// Run: npm run test:viewer (after `cargo build --release` and `npm ci` in
// the repository's root); `cargo test` runs it through tests/viewer.rs.

import { after, before, describe, test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { bake, launch, open, pick, repoDir, serve, tempDir, testAssets, tiltedPlane } from './harness.mjs';
import {
  anchoredAgreement, basis, bilinear, bspline, coefficientsAt, largestDifference, lightmapOf, projectScalar, readGlb,
  textureImage, writeGlb,
} from './decode.mjs';

const dir = tempDir();
const files = {};
let browser;
let server;

/** Pixels of a grid over the canvas, every `step` pixels. */
function grid(page, step) {
  return page.evaluate(() => window.aobakeViewer.size()).then(([w, h]) => {
    const out = [];
    for (let y = step / 2; y < h; y += step) {
      for (let x = step / 2; x < w; x += step) out.push([Math.floor(x), Math.floor(y)]);
    }
    return out;
  });
}

/** Screenshots under 'sunset' with SH relighting and without baked light. */
async function relitAndPlain(page) {
  await page.evaluate(() => window.aobakeViewer.setEnvironment('sunset', 30));
  const { PNG } = await import('pngjs');
  const shot = async (mode) => {
    await page.evaluate((m) => window.aobakeViewer.setMode(m), mode);
    return PNG.sync.read(await page.locator('#view').screenshot()).data;
  };
  return [await shot('sh'), await shot('off')];
}

function probe(page, debug, pixels) {
  return page.evaluate(([d, p]) => window.aobakeViewer.probe(d, p), [debug, pixels]);
}

/** The decoded lightmap of a baked file: the extension and its 4 images. */
function decoded(path) {
  const glb = readGlb(readFileSync(path));
  const exts = lightmapOf(glb);
  assert.ok(exts.length > 0, `${path} has baked primitives`);
  // One atlas page (version 1): every primitive names the same textures
  // and ranges; with several (version 2) each page has its own.
  const root = glb.json.extensions.AOBAKE_lightmap;
  if (root.version === 1) for (const e of exts) assert.deepEqual(e.shScale, exts[0].shScale);
  const ext = { ...exts[0], shScale: exts[0].shScale.map((_, i) => Math.max(...exts.map((e) => e.shScale[i]))) };
  const images = [ext.occlusion, ...ext.sh].map((r) => textureImage(glb, r.index));
  return { glb, ext, images };
}

/** Whether a canvas screenshot shows something: not one flat colour. */
async function canvasShowsSomething(page) {
  const png = await page.locator('#view').screenshot();
  const { PNG } = await import('pngjs');
  const img = PNG.sync.read(png);
  const first = img.data.readUInt32BE(0);
  let differ = 0;
  for (let o = 0; o < img.data.length; o += 4) differ += img.data.readUInt32BE(o) !== first;
  return { nonBlank: !(first === 0 && differ === 0), varied: differ > img.data.length / 4 / 100 };
}

before(async () => {
  files.cornell = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'),
    ['--resolution', '256', '--rays', '64']);
  files.courtyard = bake(join(testAssets, 'generated/courtyard.glb'), join(dir, 'courtyard.glb'),
    ['--resolution', '512', '--rays', '16']);
  // Several atlas pages: each primitive reads its own page's textures.
  files.courtyardPages = bake(join(testAssets, 'generated/courtyard.glb'), join(dir, 'courtyard_pages.glb'),
    ['--texel-density', '5', '--page-size', '256', '--rays', '16', '--method', 'mc']);
  // Texels fitted for the bicubic lookup, coarse enough that it matters.
  files.cornellBicubic = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell_bicubic.glb'),
    ['--resolution', '48', '--rays', '64', '--filter', 'bicubic']);
  files.plane = bake(tiltedPlane(join(dir, 'plane_in.glb')), join(dir, 'plane.glb'),
    ['--resolution', '64', '--rays', '4096']);
  // Every material of the helmet has a normal map: `auto` bakes the layer.
  files.helmet = bake(join(testAssets, 'flight_helmet.glb'), join(dir, 'helmet.glb'),
    ['--resolution', '512', '--quality', '32']);
  server = await serve(files.cornell);
  browser = await launch();
});

after(async () => {
  await browser?.close();
  server?.stop();
});

describe('uniform white environment: the relit irradiance is the baked AO', () => {
  for (const name of ['cornell', 'courtyard', 'courtyardPages']) {
    test(name, async () => {
      const page = await open(browser, server.url);
      const status = await pick(page, files[name]);
      assert.equal(status.problems.length, 0, status.message);
      assert.ok(status.baked > 0);
      if (name === 'courtyardPages') {
        const { glb } = decoded(files[name]);
        const root = glb.json.extensions.AOBAKE_lightmap;
        const pages = new Set(lightmapOf(glb).map((e) => e.occlusion.index));
        console.log(`# courtyardPages: version ${root.version}, ${root.pages.length} pages, ${pages.size} AO textures read`);
        assert.equal(root.version, 2);
        assert.ok(root.pages.length >= 3 && pages.size === root.pages.length, JSON.stringify(root.pages));
      }
      // L0 of a uniform radiance 1 is 2 sqrt(pi); nothing else.
      const L = await page.evaluate(() => window.aobakeViewer.setEnvironment('white'));
      assert.ok(Math.abs(L[0][0] - 2 * Math.sqrt(Math.PI)) < 1e-3, `L0 = ${L[0][0]}`);
      for (let i = 1; i < 9; i++) assert.ok(Math.abs(L[i][0]) < 1e-3, `L${i} = ${L[i][0]}`);
      const pixels = await grid(page, 8);
      const irr = await probe(page, 'irradiance', pixels);
      const ao = await probe(page, 'ao', pixels);
      const { ext } = decoded(files[name]);
      // 8-bit quantization: half a step of the AO texture and half a step
      // of c0's range (shScale[0]) times L0 / 0.282095 in AO units.
      const tol = 0.5 / 255 + (0.5 / 255) * ext.shScale[0] * (2 * Math.sqrt(Math.PI)) + 1e-4;
      let n = 0;
      let worst = 0;
      for (let k = 0; k < pixels.length; k++) {
        if (irr[k][3] !== 1 || ao[k][3] !== 1) continue;
        n++;
        worst = Math.max(worst, Math.abs(irr[k][0] - ao[k][0]));
        assert.ok(Math.abs(irr[k][0] - irr[k][2]) < 1e-5, 'a white environment relights grey');
      }
      assert.ok(n > 500, `${n} probe pixels on baked geometry`);
      console.log(`# ${name}: white environment, ${n} pixels, max |irradiance - AO| = ${worst.toFixed(5)} (tolerance ${tol.toFixed(5)})`);
      assert.ok(worst <= tol, `max difference ${worst} > ${tol}`);
      assert.deepEqual(page.errors, []);
      await page.close();
    });
  }
});

test('a file fitted for the bicubic lookup is sampled bicubically, and bilinearly when asked', async () => {
  const page = await open(browser, server.url);
  const status = await pick(page, files.cornellBicubic);
  assert.equal(status.problems.length, 0, status.message);
  const { glb, images } = decoded(files.cornellBicubic);
  assert.equal(glb.json.extensions.AOBAKE_lightmap.filter, 'bicubic');
  const pixels = await grid(page, 6);
  const uv = await probe(page, 'uv', pixels);
  const ao = {};
  for (const f of [null, 'bilinear']) {
    await page.evaluate((name) => window.aobakeViewer.setFilter(name), f);
    ao[f ?? 'file'] = await probe(page, 'ao', pixels);
  }
  // The GPU's bilinear fetches weigh texels with a few bits of sub-texel
  // precision; the CPU's taps are exact.
  const tol = 1.5 / 255;
  let n = 0;
  let bicubicWorst = 0;
  let bilinearWorst = 0;
  let apart = 0;
  for (let k = 0; k < pixels.length; k++) {
    if (uv[k][3] !== 1 || ao.file[k][3] !== 1) continue;
    const [u, v] = uv[k];
    const b = bspline(images[0], u, v, 0);
    const l = bilinear(images[0], u, v, 0);
    bicubicWorst = Math.max(bicubicWorst, Math.abs(ao.file[k][0] - b));
    bilinearWorst = Math.max(bilinearWorst, Math.abs(ao.bilinear[k][0] - l));
    apart = Math.max(apart, Math.abs(b - l));
    n++;
  }
  console.log(`# cornell bicubic: ${n} pixels, max |GPU - CPU| bicubic ${bicubicWorst.toExponential(2)}, bilinear path ${bilinearWorst.toExponential(2)} (tolerance ${tol.toFixed(5)}); the two lookups differ by up to ${apart.toFixed(4)}`);
  assert.ok(n > 500, `${n} probe pixels`);
  assert.ok(bicubicWorst <= tol && bilinearWorst <= tol, `${bicubicWorst} ${bilinearWorst} > ${tol}`);
  assert.ok(apart > 10 * tol, `the lookups differ by ${apart} only: the test would not tell them apart`);
  assert.deepEqual(page.errors, []);
  await page.close();
});

describe('directional environments relight as the decoded textures predict', () => {
  const lobes = { 'lobe+x': [1, 0, 0], 'lobe-x': [-1, 0, 0], 'lobe+y': [0, 1, 0], 'lobe-y': [0, -1, 0] };
  test('Cornell box, +X, -X, +Y, -Y', async () => {
    const page = await open(browser, server.url);
    await pick(page, files.cornell);
    const { ext, images } = decoded(files.cornell);
    const pixels = await grid(page, 10);
    const uv = await probe(page, 'uv', pixels);
    const thirds = {};
    for (const [name, d] of Object.entries(lobes)) {
      const pageL = await page.evaluate((n) => window.aobakeViewer.setEnvironment(n), name);
      // The test's own projection of the same lobe, 3 max(0, w.d)^4.
      const L = projectScalar((w) => 3 * Math.max(0, w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) ** 4);
      const scale = Math.max(...L.map(Math.abs));
      for (let i = 0; i < 9; i++) {
        assert.ok(Math.abs(pageL[i][0] - L[i]) < 2e-3 * scale, `${name} L${i}: page ${pageL[i][0]}, test ${L[i]}`);
      }
      const irr = await probe(page, 'irradiance', pixels);
      // Quantization of each c_i: half a step of its range, times |L_i|.
      const tol = ext.shScale.reduce((s, r, i) => s + (0.5 / 255) * r * Math.abs(L[i]), 0) + 1e-3;
      let n = 0;
      let worst = 0;
      const side = { left: [0, 0], right: [0, 0] };
      const [w] = await page.evaluate(() => window.aobakeViewer.size());
      for (let k = 0; k < pixels.length; k++) {
        if (irr[k][3] !== 1 || uv[k][3] !== 1) continue;
        const c = coefficientsAt(images, ext, uv[k][0], uv[k][1]);
        const expected = c.reduce((s, ci, i) => s + ci * L[i], 0);
        worst = Math.max(worst, Math.abs(irr[k][0] - expected));
        n++;
        const x = pixels[k][0];
        if (x < w / 3) side.left = [side.left[0] + irr[k][0], side.left[1] + 1];
        if (x > (2 * w) / 3) side.right = [side.right[0] + irr[k][0], side.right[1] + 1];
      }
      assert.ok(n > 500, `${n} probe pixels`);
      console.log(`# cornell ${name}: ${n} pixels, max |GPU - CPU relight| = ${worst.toFixed(5)} (tolerance ${tol.toFixed(5)})`);
      assert.ok(worst <= tol, `${name}: max difference ${worst} > ${tol}`);
      thirds[name] = [side.left[0] / side.left[1], side.right[0] / side.right[1]];
    }
    // The red wall (left, facing +X) is lit from +X, the green one (right,
    // facing -X) from -X: the walls swap brightness.
    const [lp, rp] = thirds['lobe+x'];
    const [lm, rm] = thirds['lobe-x'];
    console.log(`# cornell walls: +X left ${lp.toFixed(3)} right ${rp.toFixed(3)}; -X left ${lm.toFixed(3)} right ${rm.toFixed(3)}`);
    assert.ok(lp > rp + 0.05 && rm > lm + 0.05, JSON.stringify(thirds));
    assert.deepEqual(page.errors, []);
    await page.close();
  });

  test('an open receiver relights exactly as three.js LightProbe does', async () => {
    // A tilted plane with nothing around it: AO 1 everywhere, so
    // pi sum_i c_i L_i must equal three's own probe irradiance at its normal
    // (basis order, signs and the 1/pi scale of the contract against three's).
    const page = await open(browser, server.url);
    const status = await pick(page, files.plane);
    assert.equal(status.baked, 1, status.message);
    await page.evaluate(() => window.aobakeViewer.view([1.2, 1.6, 1.5], [0, 0, 0]));
    // Lit by a LightProbe of the environment's SH alone (the page's
    // default; the next test covers an environment map).
    const { ext } = decoded(files.plane);
    for (const env of ['sky', 'sunset', 'lobe+x', 'lobe-y']) {
      const L = await page.evaluate((e) => window.aobakeViewer.setEnvironment(e, 30), env);
      const pixels = await grid(page, 12);
      const irr = await probe(page, 'irradiance', pixels);
      const three = await probe(page, 'probe', pixels);
      let n = 0;
      let worst = 0;
      const tol = [0, 1, 2].map(
        (ch) => ext.shScale.reduce((s, r, i) => s + (0.5 / 255) * r * Math.abs(L[i][ch]), 0) + 1e-3,
      );
      for (let k = 0; k < pixels.length; k++) {
        if (irr[k][3] !== 1) continue;
        n++;
        for (let ch = 0; ch < 3; ch++) {
          const d = Math.abs(irr[k][ch] - three[k][ch]);
          worst = Math.max(worst, d);
          assert.ok(d <= tol[ch], `${env} channel ${ch}: ours ${irr[k][ch]}, three ${three[k][ch]}`);
        }
      }
      assert.ok(n > 200, `${n} pixels on the plane`);
      console.log(`# plane ${env}: ${n} pixels, max |ours - three LightProbe| = ${worst.toFixed(5)}`);
    }
    // Shaded, SH relighting of an open receiver is three's own probe
    // lighting ('off'): the pi of E = pi sum_i c_i L_i, the probe's
    // replacement and the albedo all agree.
    const [relit, plain] = await relitAndPlain(page);
    let worstPixel = 0;
    for (let o = 0; o < relit.length; o++) worstPixel = Math.max(worstPixel, Math.abs(relit[o] - plain[o]));
    console.log(`# plane: shaded SH relighting against three's probe lighting, max difference ${worstPixel}/255`);
    assert.ok(worstPixel <= 2, `shaded difference ${worstPixel}/255`);
    // The open receiver's decoded c_i are the clamped cosine's A_l/pi Y_i(n).
    const n = [0.48, 0.64, 0.6];
    const A = [1, 2 / 3, 2 / 3, 2 / 3, 1 / 4, 1 / 4, 1 / 4, 1 / 4, 1 / 4];
    const { images } = decoded(files.plane);
    const c = coefficientsAt(images, ext, 0.5, 0.5);
    const Y = basis(n);
    for (let i = 0; i < 9; i++) {
      assert.ok(Math.abs(c[i] - A[i] * Y[i]) < 0.01, `c${i} = ${c[i]}, open ${A[i] * Y[i]}`);
    }
    await page.close();
  });

  test('under an environment map the bake replaces its diffuse, once', async () => {
    // A PMREM of the environment's radiance as scene.environment (the
    // plugin's other kind of environment light). On the open plane the relit irradiance (the SH's)
    // is three's own IBL irradiance (the PMREM's), up to the PMREM's
    // filtering: the map's direction convention is right and the bake
    // replaces the map's diffuse instead of adding to it.
    const page = await open(browser, server.url);
    const status = await pick(page, files.plane);
    assert.equal(status.baked, 1, status.message);
    await page.evaluate(() => window.aobakeViewer.view([1.2, 1.6, 1.5], [0, 0, 0]));
    // The frames under the probe (the default), for after switching back.
    const [relitBefore] = await relitAndPlain(page);
    assert.equal(await page.evaluate(() => window.aobakeViewer.setLighting('environment')), 'environment');
    for (const env of ['sky', 'lobe+x', 'lobe-x']) {
      await page.evaluate((e) => window.aobakeViewer.setEnvironment(e, 30), env);
      const pixels = await grid(page, 12);
      const irr = await probe(page, 'irradiance', pixels);
      const ibl = await probe(page, 'probe', pixels);
      let n = 0;
      let sum = 0;
      let ref = 0;
      for (let k = 0; k < pixels.length; k++) {
        if (irr[k][3] !== 1) continue;
        n++;
        for (let ch = 0; ch < 3; ch++) {
          sum += Math.abs(irr[k][ch] - ibl[k][ch]);
          ref += ibl[k][ch];
        }
      }
      assert.ok(n > 200, `${n} pixels on the plane`);
      const relative = sum / ref;
      console.log(`# plane ${env}, environment map: mean |SH relit - three's IBL irradiance| = ${(100 * relative).toFixed(2)}% of it over ${n} pixels`);
      assert.ok(relative < 0.08, `${env}: ${relative}`);
    }
    // Shaded: with the bake replacing the map's diffuse, SH relighting of
    // the open plane looks as three's own environment lighting ('off').
    const [relit, plain] = await relitAndPlain(page);
    let sum = 0;
    let count = 0;
    for (let o = 0; o < relit.length; o += 4) {
      if (relit[o] === plain[o] && relit[o + 1] === plain[o + 1] && relit[o + 2] === plain[o + 2]) continue;
      for (let c = 0; c < 3; c++) sum += Math.abs(relit[o + c] - plain[o + c]) / 3;
      count++;
    }
    const mean = sum / Math.max(1, count);
    console.log(`# plane shaded under the environment map: ${count} pixels differ, by ${mean.toFixed(2)}/255 on average`);
    assert.ok(mean < 4, `shaded difference ${mean}/255`);
    // The bar's lighting select back to the LightProbe: the map's specular
    // is gone and SH relighting is three's own probe lighting again (as in
    // the test above), not a stale program or a black frame.
    await page.selectOption('#lighting', 'probe');
    const [relitProbe, plainProbe] = await relitAndPlain(page);
    let worstProbe = 0;
    let sinceBefore = 0;
    let changed = 0;
    for (let o = 0; o < relitProbe.length; o++) {
      worstProbe = Math.max(worstProbe, Math.abs(relitProbe[o] - plainProbe[o]));
      sinceBefore = Math.max(sinceBefore, Math.abs(relitProbe[o] - relitBefore[o]));
      changed += relit[o] !== relitProbe[o];
    }
    console.log(`# plane back under the probe: max |relit - three's probe lighting| ${worstProbe}/255, max |relit - relit before the map| ${sinceBefore}/255, ${changed} bytes differ from the frame under the map`);
    assert.ok(worstProbe <= 2, `after switching back to the probe: ${worstProbe}/255`);
    assert.ok(sinceBefore <= 1, `after switching back the frame differs from the probe's before: ${sinceBefore}/255`);
    assert.ok(changed > 0, 'the frame under the map and under the probe are the same');
    assert.deepEqual(page.errors, []);
    await page.close();
  });
});

test('an equirectangular image lights from where it is bright', async () => {
  // Top half white (sRGB 255 = radiance 1), bottom half black: +Y is the
  // image's top row, so L0 = 2 pi x 0.282095 and L(1,-1) (the y term) =
  // pi x 0.488603; every other coefficient vanishes.
  const { PNG } = await import('pngjs');
  const png = new PNG({ width: 64, height: 32 });
  for (let y = 0; y < 32; y++) {
    for (let x = 0; x < 64; x++) {
      const o = (y * 64 + x) * 4;
      png.data.fill(y < 16 ? 255 : 0, o, o + 3);
      png.data[o + 3] = 255;
    }
  }
  const path = join(dir, 'half_sky.png');
  writeFileSync(path, PNG.sync.write(png));
  const page = await open(browser, server.url);
  await page.setInputFiles('#envimage', path);
  await page.waitForFunction(() => document.getElementById('env').value === 'image');
  const L = (await page.evaluate(() => window.aobakeViewer.status())).coefficients;
  const expected = [2 * Math.PI * 0.282095, Math.PI * 0.488603, 0, 0, 0, 0, 0, 0, 0];
  for (let i = 0; i < 9; i++) {
    assert.ok(Math.abs(L[i][0] - expected[i]) < 0.02, `L${i} = ${L[i][0]}, expected ${expected[i]}`);
  }
  await page.close();
});

describe('modes', () => {
  test('AO only and no baked light differ from SH relighting where the bake matters', async () => {
    const page = await open(browser, server.url);
    await pick(page, files.cornell);
    await page.evaluate(() => window.aobakeViewer.setEnvironment('sky'));
    const shots = {};
    for (const mode of ['sh', 'ao', 'off']) {
      await page.evaluate((m) => window.aobakeViewer.setMode(m), mode);
      shots[mode] = await page.locator('#view').screenshot();
    }
    assert.notDeepEqual(shots.sh, shots.ao);
    assert.notDeepEqual(shots.ao, shots.off);
    await page.close();
  });
});

describe('files the plugin cannot use', () => {
  test('a GLB without the extension renders plainly, with a message', async () => {
    const page = await open(browser, server.url);
    const status = await pick(page, join(repoDir, 'assets/cornell_box.glb'));
    assert.equal(status.baked, 0);
    assert.equal(status.level, 'warn');
    assert.match(status.message, /has no AOBAKE_lightmap/);
    assert.ok((await canvasShowsSomething(page)).varied, 'the scene is drawn');
    await page.close();
  });

  test('a malformed extension names the primitive and what is wrong', async () => {
    const glb = readGlb(readFileSync(files.cornell));
    const json = structuredClone(glb.json);
    const prims = json.meshes.flatMap((m) => m.primitives).filter((p) => p.extensions?.AOBAKE_lightmap);
    prims[0].extensions.AOBAKE_lightmap.sh[1].index = 999;
    prims[1].extensions.AOBAKE_lightmap.shScale = prims[1].extensions.AOBAKE_lightmap.shScale.slice(0, 8);
    delete prims[2].extensions.AOBAKE_lightmap.occlusion;
    // A lookup this reader does not know: read bilinearly, and said.
    json.extensions.AOBAKE_lightmap.filter = 'lanczos';
    const path = join(dir, 'malformed.glb');
    writeFileSync(path, writeGlb(json, glb.bin));
    const page = await open(browser, server.url);
    const status = await pick(page, path);
    assert.equal(status.level, 'error');
    assert.match(status.message, /sh\[1\] names textures\[999\], which does not exist/);
    assert.match(status.message, /shScale must hold 9 numbers \(has 8\)/);
    assert.match(status.message, /occlusion has no texture index/);
    assert.match(status.message, /filter "lanczos" is not one this reader knows \(bilinear, bicubic\): read bilinearly/);
    assert.match(status.message, /meshes\[\d+\]\.primitives\[\d+\]/);
    assert.equal(status.baked, prims.length - 3, 'the other primitives keep their bake');
    assert.ok((await canvasShowsSomething(page)).varied, 'the scene is drawn');
    assert.deepEqual(page.errors, []);
    await page.close();
  });

  test('bytes that are not glTF give a message and keep the canvas drawn', async () => {
    const path = join(dir, 'garbage.glb');
    writeFileSync(path, Buffer.from('this is not a glTF file at all'));
    const page = await open(browser, server.url);
    const status = await pick(page, path);
    assert.equal(status.level, 'error');
    assert.match(status.message, /does not load/);
    assert.ok((await canvasShowsSomething(page)).nonBlank);
    await page.close();
  });
});

test('aobake view serves the page and the file, nothing outside the viewer', async () => {
  const page = await open(browser, `${server.url}`);
  const status = await page.evaluate(() => window.aobakeViewer.status());
  assert.equal(status.level, 'info', status.message);
  assert.ok(status.baked > 0);
  const base = new URL(server.url).origin;
  assert.equal((await fetch(`${base}/../Cargo.toml`)).status, 404);
  assert.equal((await fetch(`${base}/%2e%2e/Cargo.toml`)).status, 404);
  assert.equal((await fetch(`${base}/packages/aobake-three/aobake-lightmap.js`)).status, 200);
  assert.equal((await fetch(`${base}/packages/aobake-three/package.json`)).status, 404);
  await page.close();
});

describe('the visibility layer: normal maps drive the baked light', () => {
  test('flight helmet: the shader equals the CPU formula on decoded textures', async () => {
    const page = await open(browser, server.url);
    const status = await pick(page, files.helmet);
    assert.equal(status.problems.length, 0, status.message);
    const layers = await page.evaluate(() => window.aobakeViewer.layers());
    assert.ok(layers.length > 0 && layers.every((x) => x), `layers ${layers}`);
    const glb = readGlb(readFileSync(files.helmet));
    const ext = lightmapOf(glb).find((e) => e.visibility);
    assert.equal(ext.visibility.length, 4);
    const images = [ext.occlusion, ...ext.sh].map((r) => textureImage(glb, r.index));
    const vImages = ext.visibility.map((r) => textureImage(glb, r.index));
    await page.evaluate(() => window.aobakeViewer.view([0.25, 0.35, 0.45], [0, 0.3, 0]));
    const pixels = await grid(page, 12);
    const L = await page.evaluate(() => window.aobakeViewer.setEnvironment('lobe+x'));
    const probes = {};
    for (const d of ['uv', 'mapped', 'irradiance', 'shadingNormal', 'vertexNormal']) probes[d] = await probe(page, d, pixels);
    const { n, worst, moved, scale } = anchoredAgreement(probes, images, vImages, ext, L.map((l) => l[0]));
    assert.ok(n > 300, `${n} probe pixels on the helmet`);
    const tol = 2e-3 * scale;
    console.log(`# helmet lobe+x: ${n} pixels, max |GPU - CPU normal-mapped| = ${worst.toFixed(5)} (tolerance ${tol.toFixed(5)}); ${moved} moved by the normal map`);
    assert.ok(worst <= tol, `max difference ${worst} > ${tol}`);
    assert.ok(moved > n / 10, `the normal maps move only ${moved} of ${n} pixels`);
    // Normal maps off: the shading normal is the vertex normal, and the
    // formula gives c.L exactly.
    await page.evaluate(() => window.aobakeViewer.setNormalMaps(false));
    const off = await probe(page, 'mapped', pixels);
    const offPlain = await probe(page, 'irradiance', pixels);
    const worstOff = largestDifference(off, offPlain);
    console.log(`# helmet, normal maps off: max |mapped - c.L| = ${worstOff.toExponential(2)}`);
    assert.ok(worstOff < 1e-4 * scale + 1e-6, `${worstOff}`);
    await page.evaluate(() => window.aobakeViewer.setNormalMaps(true));
    assert.deepEqual(page.errors, []);
    await page.close();
  });
});
