// Screenshots for docs/engine-view.md: baked files shown AO-only under a
// uniform white environment from two views of Sponza (the hall and the
// arcade's vaults, mouldings and capitals), one PNG per file and view.
//
//   npm ci --prefix viewer
//   node viewer/engine-view-shots.mjs OUT_DIR A.glb [B.glb ...]
//
// Serves the viewer with `aobake view` (target/release/aobake, or
// AOBAKE_BIN) and drives headless Chromium (see test/harness.mjs).

import { join } from 'node:path';
import { launch, open, pick, serve } from './test/harness.mjs';
const [out, ...files] = process.argv.slice(2);
const views = {
  hall: [[-13, 2.2, 0.8], [8, 4.5, -0.5]],
  arcade: [[-6, 1.6, 3.2], [3, 5.5, 5.5]],
};
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
