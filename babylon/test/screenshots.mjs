// Screenshots of the Babylon.js importer for docs/babylon/: the Cornell box
// and Sponza under the page's sky environment, SH relighting against AO only.
//
// Run: node babylon/test/screenshots.mjs (after `cargo build --release`,
// `npm ci` in the repository's root).

import { build } from 'esbuild';
import { createServer } from 'node:http';
import { mkdirSync, readFileSync, writeFileSync, existsSync } from 'node:fs';
import { basename, join, normalize } from 'node:path';
import { bake, launch, repoDir, sharedAssets, tempDir } from '../../viewer/test/harness.mjs';

const dir = tempDir();
const out = join(repoDir, 'docs/babylon');
mkdirSync(out, { recursive: true });
const scenes = [
  ['cornell', bake(join(repoDir, 'assets/cornell_box.glb'), join(dir, 'cornell.glb'), ['--resolution', '512']), [Math.PI / 2, Math.PI / 2.1, 1.3]],
];
if (existsSync(join(sharedAssets, 'sponza_dabrovic.glb'))) {
  scenes.push(['sponza', bake(join(sharedAssets, 'sponza_dabrovic.glb'), join(dir, 'sponza.glb'), ['--resolution', '1024']), [0.3, 1.45, 0.35]]);
}
await build({
  entryPoints: [join(repoDir, 'babylon/test/page.js')], bundle: true, format: 'esm',
  outfile: join(dir, 'page.bundle.js'), logLevel: 'error',
});
writeFileSync(join(dir, 'page.html'), `<!doctype html><meta charset="utf-8"><link rel="icon" href="data:,">
<style>html, body { margin: 0; } canvas { width: 640px; height: 480px; display: block; }</style>
<canvas id="view" width="640" height="480"></canvas><script type="module" src="page.bundle.js"></script>`);
const server = createServer((req, res) => {
  const path = normalize(decodeURIComponent(new URL(req.url, 'http://x').pathname));
  try {
    const body = readFileSync(join(dir, path));
    res.writeHead(200, { 'content-type': path.endsWith('.js') ? 'text/javascript' : path.endsWith('.html') ? 'text/html' : 'model/gltf-binary' });
    res.end(body);
  } catch {
    res.writeHead(404).end();
  }
});
await new Promise((ok) => server.listen(0, '127.0.0.1', ok));
const browser = await launch();
const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
await page.goto(`http://127.0.0.1:${server.address().port}/page.html`);
await page.waitForFunction(() => window.aobakeBabylon !== undefined, null, { timeout: 120000 });
for (const [name, file, [alpha, beta, radius]] of scenes) {
  await page.evaluate((u) => window.aobakeBabylon.load(u), `/${basename(file)}`);
  await page.evaluate(([a, b, r]) => window.aobakeBabylon.view(a, b, r), [alpha, beta, radius]);
  await page.evaluate(() => window.aobakeBabylon.setEnvironment('sky'));
  for (const mode of ['sh', 'ao']) {
    await page.evaluate((m) => window.aobakeBabylon.setMode(m), mode);
    await page.evaluate(() => window.aobakeBabylon.render());
    await page.locator('#view').screenshot({ path: join(out, `${name}_${mode}.png`) });
    console.log(`docs/babylon/${name}_${mode}.png`);
  }
}
await browser.close();
server.close();
