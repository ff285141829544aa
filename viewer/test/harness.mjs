// Shared by the browser tests and the screenshot script: bakes scenes with
// the aobake binary, serves the viewer with `aobake view`, and drives
// Debian's Chromium through playwright-core.
//
// Environment: AOBAKE_BIN (the aobake binary; default the release build),
// CHROMIUM (default /usr/bin/chromium), AOBAKE_SHARED (the shared test
// assets; default ../shared/assets beside the repository),
// AOBAKE_BAKE_CACHE (a folder where bakes are kept by binary, input and
// arguments, so that test files asking for the same bake share one; a bake
// is deterministic, so a kept one is the bytes a new one would write).

import { spawn, execFileSync } from 'node:child_process';
import { createHash } from 'node:crypto';
import { copyFileSync, existsSync, mkdirSync, mkdtempSync, readFileSync, renameSync, writeFileSync } from 'node:fs';
import { writeGlb } from './decode.mjs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

export const viewerDir = resolve(dirname(fileURLToPath(import.meta.url)), '..');
export const repoDir = resolve(viewerDir, '..');
export const aobake = process.env.AOBAKE_BIN ?? join(repoDir, 'target/release/aobake');
export const chromiumPath = process.env.CHROMIUM ?? '/usr/bin/chromium';
// The test scenes in the repository (assets/CREDITS.md): every clone has them.
export const testAssets = resolve(repoDir, 'assets');
export const sharedAssets = process.env.AOBAKE_SHARED ?? resolve(repoDir, '../shared/assets');

export function tempDir() {
  return mkdtempSync(join(tmpdir(), 'aobake-viewer-'));
}

let binaryDigest;

/**
 * Bakes `input` into `output` with extra CLI arguments (with
 * AOBAKE_BAKE_CACHE set: a copy of the same binary's bake of the same
 * input bytes with the same arguments when there is one).
 */
export function bake(input, output, args = []) {
  const cache = process.env.AOBAKE_BAKE_CACHE;
  let kept = null;
  if (cache) {
    binaryDigest ??= createHash('sha256').update(readFileSync(aobake)).digest();
    const key = createHash('sha256').update(binaryDigest).update(readFileSync(input))
      .update(JSON.stringify(args)).digest('hex').slice(0, 32);
    kept = join(cache, `${key}.glb`);
    if (existsSync(kept)) {
      copyFileSync(kept, output);
      return output;
    }
  }
  execFileSync(aobake, [input, output, '-q', ...args], { stdio: 'inherit' });
  if (kept) {
    // Kept under a temporary name first: a run killed midway leaves no
    // half-written file under the key.
    mkdirSync(cache, { recursive: true });
    const part = `${kept}.${process.pid}.part`;
    copyFileSync(output, part);
    renameSync(part, kept);
  }
  return output;
}

/**
 * Starts `aobake view` on a free port; resolves to { url, stop }. By
 * default it serves this checkout's viewer/; with `builtIn` the copy built
 * into the binary, run from `cwd` (as an installed binary would be).
 */
export function serve(model, { builtIn = false, cwd = undefined } = {}) {
  const args = ['view', '--port', '0'];
  if (!builtIn) args.push('--viewer-dir', viewerDir);
  if (model) args.push(model);
  const child = spawn(aobake, args, { stdio: ['ignore', 'pipe', 'inherit'], cwd });
  return new Promise((ok, fail) => {
    let out = '';
    child.on('exit', (code) => fail(new Error(`aobake view exited (${code}): ${out}`)));
    child.stdout.on('data', (d) => {
      out += d;
      const m = out.match(/http:\/\/127\.0\.0\.1:\d+\/\S*/);
      if (m) ok({ url: m[0], stop: () => child.kill() });
    });
  });
}

/** Headless Chromium with software WebGL and no network beyond loopback. */
export async function launch() {
  return chromium.launch({
    executablePath: chromiumPath,
    args: [
      '--no-sandbox',
      '--disable-gpu',
      '--use-angle=swiftshader',
      '--enable-unsafe-swiftshader',
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
    ],
  });
}

/** A page of the viewer at `url`, its errors collected in `page.errors`. */
export async function open(browser, url, viewport = { width: 800, height: 600 }) {
  const page = await browser.newPage({ viewport });
  page.errors = [];
  page.on('pageerror', (e) => page.errors.push(e.message));
  page.on('console', (m) => { if (m.type() === 'error') page.errors.push(m.text()); });
  await page.goto(url);
  // index.html imports the engine's page module dynamically.
  await page.waitForFunction(() => window.aobakeViewer !== undefined, null, { timeout: 120000 });
  await page.evaluate(() => window.aobakeViewer.ready);
  return page;
}

/** Opens a local file through the page's file picker; resolves to the status. */
export async function pick(page, path) {
  const before = await page.evaluate(() => window.aobakeViewer.status().message);
  await page.setInputFiles('#file', path);
  await page.waitForFunction(
    (b) => {
      const m = window.aobakeViewer.status().message;
      return m !== b && !m.startsWith('loading');
    },
    before,
  );
  return page.evaluate(() => window.aobakeViewer.status());
}

/** A 1x1 quad tilted so that every SH basis function matters, as a GLB;
 * `material`: a glTF material object for it (none by default). */
export function tiltedPlane(path, { material = null } = {}) {
  const n = [0.48, 0.64, 0.6];
  const t = [0.8, -0.6, 0];
  const b = [n[1] * t[2] - n[2] * t[1], n[2] * t[0] - n[0] * t[2], n[0] * t[1] - n[1] * t[0]];
  const corner = (s, r) => [0, 1, 2].map((k) => (s - 0.5) * t[k] + (r - 0.5) * b[k]);
  const pos = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)].flat();
  const nor = [n, n, n, n].flat();
  const idx = [0, 1, 2, 0, 2, 3];
  const bin = Buffer.concat([
    Buffer.from(new Float32Array(pos).buffer),
    Buffer.from(new Float32Array(nor).buffer),
    Buffer.from(new Uint16Array(idx).buffer),
  ]);
  const min = [0, 1, 2].map((k) => Math.min(...[0, 1, 2, 3].map((v) => pos[v * 3 + k])));
  const max = [0, 1, 2].map((k) => Math.max(...[0, 1, 2, 3].map((v) => pos[v * 3 + k])));
  const json = {
    asset: { version: '2.0' },
    scene: 0,
    scenes: [{ nodes: [0] }],
    nodes: [{ mesh: 0 }],
    meshes: [{ primitives: [{ attributes: { POSITION: 0, NORMAL: 1 }, indices: 2 }] }],
    buffers: [{ byteLength: bin.length }],
    bufferViews: [
      { buffer: 0, byteOffset: 0, byteLength: 48 },
      { buffer: 0, byteOffset: 48, byteLength: 48 },
      { buffer: 0, byteOffset: 96, byteLength: 12 },
    ],
    accessors: [
      { bufferView: 0, componentType: 5126, count: 4, type: 'VEC3', min, max },
      { bufferView: 1, componentType: 5126, count: 4, type: 'VEC3' },
      { bufferView: 2, componentType: 5123, count: 6, type: 'SCALAR' },
    ],
  };
  if (material) {
    json.materials = [material];
    json.meshes[0].primitives[0].material = 0;
  }
  writeFileSync(path, writeGlb(json, bin));
  return path;
}
