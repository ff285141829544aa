// Screenshots of the viewer for the docs: the Cornell box and Sponza, each
// relit with its SH lightmaps under two environments, and the flight helmet
// with and without the visibility layer (its normal maps in the baked light).
//
//   cargo build --release && npm ci
//   node viewer/screenshots.mjs [OUT_DIR (docs/viewer)] [SCENE ...]
//
// Bakes the scenes with target/release/aobake (or AOBAKE_BIN) into a
// temporary directory, serves the viewer with `aobake view` and drives
// headless Chromium (see test/harness.mjs).

import { mkdirSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { bake, launch, open, pick, repoDir, serve, sharedAssets, tempDir } from './test/harness.mjs';

const out = resolve(process.argv[2] ?? join(repoDir, 'docs/viewer'));
const only = process.argv.slice(3);
mkdirSync(out, { recursive: true });
const dir = tempDir();
const helmetView = [[0.22, 0.36, 0.3], [0, 0.33, 0]];
const all = [
  {
    name: 'cornell',
    make: () => bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'), ['--resolution', '512', '--rays', '256']),
    view: null,
    environments: ['sky', 'sunset'],
  },
  {
    name: 'sponza',
    make: () => bake(join(sharedAssets, 'sponza_dabrovic.glb'), join(dir, 'sponza.glb'), ['--resolution', '1024', '--rays', '128']),
    view: [[-13, 2.2, 0.8], [8, 4.5, -0.5]],
    environments: ['sky', 'sunset'],
  },
  {
    name: 'helmet_layer',
    make: () => bake(join(sharedAssets, 'flight_helmet.glb'), join(dir, 'helmet.glb'), ['--resolution', '1024']),
    view: helmetView,
    environments: ['lobe+x'],
  },
  {
    name: 'helmet_no_layer',
    make: () => bake(join(sharedAssets, 'flight_helmet.glb'), join(dir, 'helmet_off.glb'), ['--resolution', '1024', '--visibility', 'off']),
    view: helmetView,
    environments: ['lobe+x'],
  },
];
const scenes = all
  .filter((s) => only.length === 0 || only.some((o) => s.name.startsWith(o)))
  .map((s) => ({ ...s, file: s.make() }));
const server = await serve();
const browser = await launch();
try {
  for (const s of scenes) {
    const page = await open(browser, server.url, { width: 960, height: 680 });
    const status = await pick(page, s.file);
    if (status.problems.length > 0 || status.baked === 0) throw new Error(status.message);
    if (s.view) await page.evaluate(([p, t]) => window.aobakeViewer.view(p, t), s.view);
    for (const env of s.environments) {
      await page.evaluate((e) => window.aobakeViewer.setEnvironment(e, 0), env);
      await page.evaluate(() => window.aobakeViewer.setMode('sh'));
      const path = join(out, `${s.name}_${env}.png`);
      await page.locator('#view').screenshot({ path });
      console.log(`wrote ${path}`);
    }
    await page.close();
  }
} finally {
  await browser.close();
  server.stop();
}
