// The Babylon.js importer (the package aobake-babylon) in a real browser
// (Debian's Chromium, headless, SwiftShader WebGL2), against expectations
// computed here from the decoded textures, independently of the shader and
// of Babylon: the relit value sum_i c_i L_i at probe pixels, with c_i read
// bilinearly from the PNGs at the pixel's lightmap UV and L_i this test's
// own projection of the environment's radiance function (in the bake's
// frame, through the loader's root matrix).
//
// Run: npm run test:babylon (after `cargo build --release` and `npm ci` in
// the repository's root); `cargo test` runs it through tests/babylon.rs.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { createServer } from 'node:http';
import { readFileSync, writeFileSync } from 'node:fs';
import { basename, extname, join, normalize } from 'node:path';
import { build } from 'esbuild';
import { bake, launch, repoDir, tempDir, testAssets, tiltedPlane } from '../../viewer/test/harness.mjs';
import {
  anchoredAgreement, bilinear, bspline, coefficientsAt, largestDifference, lightmapOf, projectScalar, readGlb, textureImage,
  writeGlb,
} from '../../viewer/test/decode.mjs';

const dir = tempDir();
const files = {};
let browser;
let server;
let base;

/** Serves the repository (the page, the importer, node_modules) and /files/ (the bakes). */
function startServer() {
  const types = { '.js': 'text/javascript', '.mjs': 'text/javascript', '.html': 'text/html', '.glb': 'model/gltf-binary', '.json': 'application/json' };
  server = createServer((req, res) => {
    const path = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    const file = path.startsWith('/files/') ? join(dir, normalize(path.slice(7))) : join(repoDir, normalize(path));
    if (!file.startsWith(dir) && !file.startsWith(repoDir)) {
      res.writeHead(403).end();
      return;
    }
    try {
      const body = readFileSync(file);
      res.writeHead(200, { 'content-type': types[extname(file)] ?? 'application/octet-stream' });
      res.end(body);
    } catch {
      res.writeHead(404).end();
    }
  });
  return new Promise((ok) => server.listen(0, '127.0.0.1', () => {
    base = `http://127.0.0.1:${server.address().port}`;
    ok();
  }));
}

function grid([w, h], step) {
  const out = [];
  for (let y = step / 2; y < h; y += step) for (let x = step / 2; x < w; x += step) out.push([Math.floor(x), Math.floor(y)]);
  return out;
}

async function openPage() {
  const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') page.errors.push(m.text()); });
  await page.goto(`${base}/files/page.html`);
  await page.waitForFunction(() => window.aobakeBabylon !== undefined, null, { timeout: 120000 });
  return page;
}

/** Radiance functions of a Babylon-world direction, as the page defines them. */
const lobe = (d) => (w) => 3 * Math.max(0, w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) ** 4;
const ENVIRONMENTS = {
  white: () => 1,
  'lobe+x': lobe([1, 0, 0]), 'lobe-x': lobe([-1, 0, 0]), 'lobe+y': lobe([0, 1, 0]), 'lobe-y': lobe([0, -1, 0]), 'lobe+z': lobe([0, 0, 1]),
};

/** This test's L_i in the bake's frame: f(M w), M the root's matrix (row-major). */
function expectedL(name, M) {
  const f = ENVIRONMENTS[name];
  return projectScalar((w) => {
    const d = [0, 1, 2].map((r) => M[3 * r] * w[0] + M[3 * r + 1] * w[1] + M[3 * r + 2] * w[2]);
    const len = Math.hypot(...d);
    return f(d.map((e) => e / len));
  });
}

function decoded(path) {
  const glb = readGlb(readFileSync(path));
  return { glb, exts: lightmapOf(glb) };
}

before(async () => {
  files.cornell = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'), ['--resolution', '256', '--rays', '64']);
  // Texels fitted for the bicubic lookup, coarse enough that it matters.
  files.cornellBicubic = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell_bicubic.glb'),
    ['--resolution', '48', '--rays', '64', '--filter', 'bicubic']);
  files.plane = bake(tiltedPlane(join(dir, 'plane_in.glb'), {
    material: { pbrMetallicRoughness: { metallicFactor: 0, roughnessFactor: 1 } },
  }), join(dir, 'plane.glb'), ['--resolution', '64', '--rays', '4096']);
  files.courtyardPages = bake(join(testAssets, 'generated/courtyard.glb'), join(dir, 'courtyard_pages.glb'),
    ['--texel-density', '5', '--page-size', '256', '--rays', '16', '--method', 'mc']);
  // Every material of the helmet has a normal map: `auto` bakes the layer.
  files.helmet = bake(join(testAssets, 'flight_helmet.glb'), join(dir, 'helmet.glb'), ['--resolution', '512', '--quality', '32']);
  // The page and Babylon as one module (thousands of ES modules load too slowly).
  await build({
    entryPoints: [join(repoDir, 'babylon/test/page.js')], bundle: true, format: 'esm',
    outfile: join(dir, 'page.bundle.js'), logLevel: 'error',
  });
  writeFileSync(join(dir, 'page.html'), `<!doctype html><meta charset="utf-8"><title>aobake Babylon.js test</title><link rel="icon" href="data:,">
<style>html, body { margin: 0; } canvas { width: 640px; height: 480px; display: block; }</style>
<canvas id="view" width="640" height="480"></canvas><script type="module" src="page.bundle.js"></script>`);
  await startServer();
  browser = await launch();
});

after(async () => {
  await browser?.close();
  server?.close();
});

/**
 * Probes `name` under each environment: the shader's c.L against the CPU's
 * at every probe pixel, the CPU reading the textures with `sample` and the
 * importer with `filter` (null: as the file says); returns the pixels
 * compared, the worst difference and how far the other lookup's c.L lies
 * from the CPU's (`apart`).
 */
async function relightMatches(name, environments, views = [[-Math.PI / 2, Math.PI / 2.5]], { filter = null, sample = bilinear } = {}) {
  const page = await openPage();
  const status = await page.evaluate((u) => window.aobakeBabylon.load(u), `/files/${basename(files[name])}`);
  assert.deepEqual(status.problems, []);
  assert.ok(status.baked > 0);
  if (filter) await page.evaluate((f) => window.aobakeBabylon.setFilter(f), filter);
  const other = sample === bilinear ? bspline : bilinear;
  let apart = 0;
  const { glb, exts } = decoded(files[name]);
  // Each page's extension (ranges) and decoded images.
  const pages = new Map();
  for (const e of exts) {
    const p = e.page ?? 0;
    if (!pages.has(p)) pages.set(p, { e, images: [e.occlusion, ...e.sh].map((r) => textureImage(glb, r.index)) });
  }
  const M = await page.evaluate(() => window.aobakeBabylon.toScene());
  const size = await page.evaluate(() => window.aobakeBabylon.size());
  let total = 0;
  let worstAll = 0;
  for (const [alpha, beta] of views) {
    await page.evaluate(([a, b]) => window.aobakeBabylon.view(a, b), [alpha, beta]);
    const pixels = grid(size, 8);
    for (const env of environments) {
      const pageL = await page.evaluate((n) => window.aobakeBabylon.setEnvironment(n), env);
      const L = expectedL(env, M);
      const scale = Math.max(...L.map(Math.abs));
      // The importer's conversion of Babylon's polynomial: Babylon's
      // cube-map quadrature (32^2 per face) against this test's.
      for (let i = 0; i < 9; i++) {
        assert.ok(Math.abs(pageL[i][0] - L[i]) < 4e-3 * scale, `${env} L${i}: importer ${pageL[i][0]}, test ${L[i]}`);
      }
      // u, v, c.L and page + 1 of one fragment (coplanar surfaces, as in
      // Sponza, would pair one surface's UV with another's light).
      const probed = await page.evaluate(([d, p]) => window.aobakeBabylon.probe(d, p), ['uvIrradiancePage', pixels]);
      let n = 0;
      let worst = 0;
      let excess = -Infinity;
      let tolAtWorst = 0;
      for (let k = 0; k < pixels.length; k++) {
        const [u, v, relit, pagePlus1] = probed[k];
        if (pagePlus1 < 0.5) continue;
        const { e, images } = pages.get(Math.round(pagePlus1) - 1);
        const c = coefficientsAt(images, e, u, v, sample);
        const expected = c.reduce((s, ci, i) => s + ci * L[i], 0);
        const alt = coefficientsAt(images, e, u, v, other).reduce((s, ci, i) => s + ci * L[i], 0);
        apart = Math.max(apart, Math.abs(alt - expected));
        // Quantization of each c_i (half a step of its range, times |L_i|),
        // plus the two projections' difference.
        const tol = e.shScale.reduce((s, r, i) => s + (0.5 / 255) * r * Math.abs(L[i]), 0) + 1e-3 * scale + 1e-4;
        const d = Math.abs(relit - expected);
        if (process.env.AOBAKE_DEBUG && d > tol) {
          const others = [...pages.entries()].map(([pg, o]) => [pg, coefficientsAt(o.images, o.e, u, v).reduce((s, ci, i) => s + ci * L[i], 0).toFixed(4)]);
          console.log('# off', pixels[k], u.toFixed(5), v.toFixed(5), relit.toFixed(4), expected.toFixed(4), pagePlus1, JSON.stringify(others));
        }
        worst = Math.max(worst, d);
        if (d - tol > excess) {
          excess = d - tol;
          tolAtWorst = tol;
        }
        n++;
      }
      assert.ok(n > 300, `${name} ${env}: ${n} probe pixels on baked geometry`);
      console.log(`# ${name} ${env}: ${n} pixels, max |GPU - CPU relight| = ${worst.toFixed(5)}; closest to its tolerance: ${(excess + tolAtWorst).toFixed(5)} of ${tolAtWorst.toFixed(5)}`);
      assert.ok(excess <= 0, `${name} ${env}: ${excess + tolAtWorst} > ${tolAtWorst}`);
      total += n;
      worstAll = Math.max(worstAll, worst);
    }
  }
  assert.deepEqual(page.errors, []);
  await page.close();
  return { total, worst: worstAll, apart };
}

test('the loader root is a mirror, read from the scene', async () => {
  const page = await openPage();
  await page.evaluate((u) => window.aobakeBabylon.load(u), '/files/cornell.glb');
  const M = await page.evaluate(() => window.aobakeBabylon.toScene());
  const det = M[0] * (M[4] * M[8] - M[5] * M[7]) - M[1] * (M[3] * M[8] - M[5] * M[6]) + M[2] * (M[3] * M[7] - M[4] * M[6]);
  console.log(`# glTF -> Babylon world: ${M.map((v) => v.toFixed(3)).join(' ')} (det ${det.toFixed(3)})`);
  // Babylon is left-handed: glTF's right-handed frame arrives mirrored.
  assert.ok(Math.abs(det + 1) < 1e-6, `det ${det}`);
  await page.close();
});

test('Cornell box: uniform and directional environments relight as the decoded textures predict', async () => {
  await relightMatches('cornell', ['white', 'lobe+x', 'lobe-x', 'lobe+y', 'lobe-y', 'lobe+z']);
});

test('a file fitted for the bicubic lookup relights bicubically, and bilinearly when asked', async () => {
  assert.equal(decoded(files.cornellBicubic).glb.json.extensions.AOBAKE_lightmap.filter, 'bicubic');
  const envs = ['white', 'lobe+x', 'lobe-y'];
  const bicubic = await relightMatches('cornellBicubic', envs, undefined, { sample: bspline });
  const linear = await relightMatches('cornellBicubic', envs, undefined, { filter: 'bilinear', sample: bilinear });
  console.log(`# cornell bicubic: the other lookup's c.L differs by up to ${bicubic.apart.toFixed(4)} (bicubic path) and ${linear.apart.toFixed(4)} (bilinear path)`);
  // Each path matches its own CPU lookup within the tolerance (about
  // 0.005) where the other lookup lies far off.
  assert.ok(bicubic.apart > 0.05 && linear.apart > 0.05, `${bicubic.apart} ${linear.apart}`);
});

test('a tilted open plane: every coefficient matters', async () => {
  await relightMatches('plane', ['lobe+x', 'lobe+y', 'lobe+z'], [[0.4, 1.0], [1.2, 0.8]]);
});

test('an open receiver relights as Babylon lights it from its own environment', async () => {
  // The plane is open: its c_i are the cosine lobe's (A_l / pi) Y_i(n) up
  // to the bake's noise (4096 rays), so c.L must equal what Babylon's PBR
  // shader computes for the same environment at the same fragment.
  const page = await openPage();
  await page.evaluate((u) => window.aobakeBabylon.load(u), `/files/${basename(files.plane)}`);
  const size = await page.evaluate(() => window.aobakeBabylon.size());
  const pixels = grid(size, 8);
  // The front face (the baked side; back faces are culled).
  await page.evaluate(() => window.aobakeBabylon.view(0.4, 1.0));
  for (const env of ['white', 'lobe+x', 'lobe+y', 'lobe+z']) {
    await page.evaluate((n) => window.aobakeBabylon.setEnvironment(n), env);
    const relit = await page.evaluate(([d, p]) => window.aobakeBabylon.probe(d, p), ['irradiance', pixels]);
    const own = await page.evaluate(([d, p]) => window.aobakeBabylon.probe(d, p), ['environment', pixels]);
    let n = 0;
    let sum = 0;
    let worst = 0;
    let level = 0;
    for (let k = 0; k < pixels.length; k++) {
      if (relit[k][3] !== 1 || own[k][3] !== 1) continue;
      const d = Math.abs(relit[k][0] - own[k][0]);
      sum += d;
      worst = Math.max(worst, d);
      level = Math.max(level, own[k][0]);
      n++;
    }
    assert.ok(n > 300, `${n} pixels`);
    console.log(`# open plane ${env}: Babylon's own E/pi up to ${level.toFixed(4)}; c.L against it: mean ${(sum / n).toFixed(5)}, max ${worst.toFixed(5)} over ${n} pixels`);
    assert.ok(worst <= 0.02 * level + 0.004, `${env}: ${worst} against ${level}`);
  }
  assert.deepEqual(page.errors, []);
  await page.close();
});

test('malformed extensions are reported by primitive, and the rest still relights', async () => {
  const glb = readGlb(readFileSync(files.cornell));
  const prims = glb.json.meshes.flatMap((m, mi) => m.primitives.map((p, pi) => [mi, pi, p]))
    .filter(([, , p]) => p.extensions?.AOBAKE_lightmap);
  const [m0, p0, a] = prims[0];
  const [m1, p1, b] = prims[1];
  a.extensions.AOBAKE_lightmap.shScale = [1, 2, 3];
  b.extensions.AOBAKE_lightmap.sh[1] = { index: 999 };
  const path = join(dir, 'cornell_broken.glb');
  writeFileSync(path, writeGlb(glb.json, glb.bin));
  const page = await openPage();
  const status = await page.evaluate((u) => window.aobakeBabylon.load(u), `/files/${basename(path)}`);
  console.log(`# malformed: ${JSON.stringify(status.problems)}`);
  assert.deepEqual(status.problems, [
    `meshes[${m0}].primitives[${p0}] AOBAKE_lightmap: shScale must hold 9 numbers (has 3)`,
    `meshes[${m1}].primitives[${p1}] AOBAKE_lightmap: sh[1] names textures[999], which does not exist`,
  ]);
  assert.equal(status.baked, prims.length - 2);
  assert.deepEqual(page.errors, []);
  await page.close();
});

test('the courtyard on several atlas pages: each primitive reads its own page', async () => {
  const root = decoded(files.courtyardPages).glb.json.extensions.AOBAKE_lightmap;
  assert.ok(root.pages.length >= 3);
  await relightMatches('courtyardPages', ['white', 'lobe+y']);
});

test('flight helmet: normal maps drive the baked light as the CPU formula says', async () => {
  const page = await openPage();
  const status = await page.evaluate((u) => window.aobakeBabylon.load(u), `/files/${basename(files.helmet)}`);
  assert.deepEqual(status.problems, []);
  const layers = await page.evaluate(() => window.aobakeBabylon.layers());
  assert.ok(layers.length > 0 && layers.every((x) => x), `layers ${layers}`);
  const { glb, exts } = decoded(files.helmet);
  const ext = exts.find((e) => e.visibility);
  assert.equal(ext.visibility.length, 4);
  const images = [ext.occlusion, ...ext.sh].map((r) => textureImage(glb, r.index));
  const vImages = ext.visibility.map((r) => textureImage(glb, r.index));
  await page.evaluate(() => window.aobakeBabylon.lookAt([0.25, 0.35, 0.45], [0, 0.3, 0]));
  const size = await page.evaluate(() => window.aobakeBabylon.size());
  const pixels = grid(size, 12);
  const L = (await page.evaluate((n) => window.aobakeBabylon.setEnvironment(n), 'lobe+x')).map((l) => l[0]);
  const probe = (d) => page.evaluate(([dd, p]) => window.aobakeBabylon.probe(dd, p), [d, pixels]);
  const probes = {};
  for (const d of ['uv', 'mapped', 'irradiance', 'shadingNormal', 'vertexNormal']) probes[d] = await probe(d);
  const { n, worst, moved, scale } = anchoredAgreement(probes, images, vImages, ext, L);
  assert.ok(n > 300, `${n} probe pixels on the helmet`);
  const tol = 2e-3 * scale;
  console.log(`# helmet lobe+x: ${n} pixels, max |GPU - CPU normal-mapped| = ${worst.toFixed(5)} (tolerance ${tol.toFixed(5)}); ${moved} moved by the normal map`);
  assert.ok(worst <= tol, `max difference ${worst} > ${tol}`);
  assert.ok(moved > n / 10, `the normal maps move only ${moved} of ${n} pixels`);
  // Normal maps off: n' = n, and the formula gives c.L exactly.
  await page.evaluate(() => window.aobakeBabylon.setNormalMaps(false));
  const off = await probe('mapped');
  const offPlain = await probe('irradiance');
  const worstOff = largestDifference(off, offPlain);
  console.log(`# helmet, normal maps off: max |mapped - c.L| = ${worstOff.toExponential(2)}`);
  assert.ok(worstOff < 1e-4 * scale + 1e-6, `${worstOff}`);
  await page.evaluate(() => window.aobakeBabylon.setNormalMaps(true));
  assert.deepEqual(page.errors, []);
  await page.close();
});
