// Screenshots for docs/engine-view.md: baked files shown AO-only under a
// uniform white environment, one PNG per file and view. The views: Sponza's
// (the hall, the arcade's vaults, mouldings and capitals, and a close-up
// of them) by default, or with --views helmet the flight helmet's (the
// goggles and straps, the hose and the leather, close up).
//
//   npm ci
//   node viewer/engine-view-shots.mjs OUT_DIR [--views sponza|helmet] A.glb [B.glb ...]
//
// Serves the viewer with `aobake view` (target/release/aobake, or
// AOBAKE_BIN) and drives headless Chromium (see test/harness.mjs).

import { join } from 'node:path';
import { launch, open, pick, serve } from './test/harness.mjs';
const args = process.argv.slice(2);
const out = args.shift();
let preset = 'sponza';
if (args[0] === '--views') {
  args.shift();
  preset = args.shift();
}
const files = args;
const presets = {
  sponza: {
    hall: [[-13, 2.2, 0.8], [8, 4.5, -0.5]],
    arcade: [[-6, 1.6, 3.2], [3, 5.5, 5.5]],
    corbel: [[-4.9, 2.0, 4.4], [-3.5, 2.2, 6.0]],
    capital: [[-4.86, 1.92, 3.03], [-3.14, 2.41, 2.78]],
  },
  helmet: {
    goggles: [[0.14, 0.62, 0.42], [0.0, 0.56, 0.12]],
    hose: [[0.3, 0.3, 0.38], [0.0, 0.25, 0.05]],
  },
};
const views = presets[preset];
if (!views) throw new Error(`unknown --views ${preset} (sponza, helmet)`);
const server = await serve();
const browser = await launch();
try {
  for (const f of files) {
    const page = await open(browser, server.url, { width: 960, height: 680 });
    const status = await pick(page, f);
    if (status.problems.length > 0 || status.baked === 0) throw new Error(status.message);
    await page.evaluate(() => window.aobakeViewer.setEnvironment('white', 0));
    await page.evaluate(() => window.aobakeViewer.setMode('ao'));
    for (const [name, v] of Object.entries(views)) {
      await page.evaluate(([p, t]) => window.aobakeViewer.view(p, t), v);
      const tag = f.split('/').pop().replace('.glb', '');
      const path = join(out, `${tag}_${name}.png`);
      await page.locator('#view').screenshot({ path });
      console.log(`wrote ${path}`);
    }
    await page.close();
  }
} finally {
  await browser.close();
  server.stop();
}
