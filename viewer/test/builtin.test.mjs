// `aobake view` without --viewer-dir, run from a directory that is not the
// checkout: the page and three.js are served from the copy built into the
// binary, as for an installed `aobake` (`cargo install --path .`; .ci/run
// runs this file against one).
//
// Run: AOBAKE_BIN=path/to/aobake node --test test/builtin.test.mjs

import { after, before, test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { gunzipSync } from 'node:zlib';
import { join } from 'node:path';
import { bake, launch, open, repoDir, serve, tempDir, viewerDir } from './harness.mjs';

const dir = tempDir();
let browser;
let server;

before(async () => {
  const baked = bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'),
    ['--resolution', '128', '--rays', '16']);
  server = await serve(baked, { builtIn: true, cwd: dir });
  browser = await launch();
});

after(async () => {
  await browser?.close();
  server?.stop();
});

test('the built-in page loads the model, relights it and draws', async () => {
  const page = await open(browser, server.url);
  const status = await page.evaluate(() => window.aobakeViewer.status());
  assert.equal(status.level, 'info', status.message);
  assert.ok(status.baked > 0, 'baked primitives found');
  assert.deepEqual(page.errors, []);
  await page.evaluate(() => window.aobakeViewer.setEnvironment('white'));
  const png = await page.locator('canvas').screenshot();
  // A drawn frame: not one colour.
  const distinct = new Set();
  for (let i = 0; i < png.length; i += 97) distinct.add(png[i]);
  assert.ok(distinct.size > 8, `canvas drew ${distinct.size} distinct byte values`);
  await page.close();
});

test('the built-in Babylon.js page loads the model too, and the bundle arrives gzip-encoded', async () => {
  const page = await open(browser, `${server.url}&engine=babylon`);
  const status = await page.evaluate(() => window.aobakeViewer.status());
  assert.equal(status.level, 'info', status.message);
  assert.ok(status.baked > 0, 'baked primitives found');
  assert.equal(await page.evaluate(() => window.aobakeViewer.engine), 'babylon');
  assert.deepEqual(page.errors, []);
  await page.close();
  const base = new URL(server.url).origin;
  const res = await fetch(`${base}/vendor/babylon/aobake-babylon.js`);
  assert.equal(res.headers.get('content-encoding'), 'gzip');
  assert.match(res.headers.get('content-type'), /javascript/);
  const got = Buffer.from(await res.arrayBuffer());
  assert.ok(got.equals(gunzipSync(readFileSync(join(viewerDir, 'vendor/babylon/aobake-babylon.js.gz')))));
});

test('the built-in files are this checkout\'s, and nothing else is served', async () => {
  const base = new URL(server.url).origin;
  for (const f of ['viewer.js', 'bar.js', 'babylon-viewer.js', 'compare.js', 'vendor/three/build/three.module.js']) {
    const got = Buffer.from(await (await fetch(`${base}/${f}`)).arrayBuffer());
    assert.ok(got.equals(readFileSync(join(viewerDir, f))), `${f} differs from viewer/${f}`);
  }
  // The packages the page imports, served where its import map names them.
  for (const f of ['packages/aobake-three/aobake-lightmap.js', 'packages/aobake-contract/index.js', 'packages/aobake-contract/sh.js']) {
    const got = Buffer.from(await (await fetch(`${base}/${f}`)).arrayBuffer());
    assert.ok(got.equals(readFileSync(join(repoDir, f))), `${f} differs from the checkout's`);
  }
  for (const f of ['package.json', '../Cargo.toml', 'node_modules/three/package.json', 'test/harness.mjs', 'packages/aobake-three/package.json', 'packages/test/pack.test.mjs']) {
    assert.equal((await fetch(`${base}/${f}`)).status, 404, f);
  }
});
