// The engine importers as a user installs them: packs each package in
// packages/ with `npm pack`, installs the three tarballs into a clean
// temporary project (their engines come in as peer dependencies), and
// imports them there with node and with a bundler (esbuild).
//
// Checked: each tarball holds exactly the files its package.json lists;
// the contract's numbers against closed forms (SH projections, the triple
// product's orthonormality); the Babylon.js importer registers itself in
// the user's own copy of @babylonjs/loaders (one instance, so the loader
// finds it); one copy of the contract and of each engine in the project
// and in a bundle of both importers.
//
// Run: npm run test:packages (after `npm ci` in the repository's root; it
// needs npm and the registry or npm's cache for the engines); `cargo test`
// runs it through tests/packages.rs.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { build } from 'esbuild';

const packagesDir = resolve(dirname(fileURLToPath(import.meta.url)), '..');
const NAMES = ['aobake-contract', 'aobake-three', 'aobake-babylon'];
const root = resolve(packagesDir, '..');
const pinned = JSON.parse(readFileSync(join(root, 'package.json'), 'utf8')).devDependencies;

let dir;
const packed = {};

function npm(args, cwd) {
  return execFileSync('npm', [...args, '--no-audit', '--no-fund', '--loglevel=error'], { cwd, encoding: 'utf8' });
}

before(() => {
  dir = mkdtempSync(join(tmpdir(), 'aobake-packages-'));
  for (const name of NAMES) {
    const [info] = JSON.parse(npm(['pack', '--json', '--pack-destination', dir], join(packagesDir, name)));
    packed[name] = info;
  }
  const project = join(dir, 'project');
  execFileSync('mkdir', [project]);
  writeFileSync(join(project, 'package.json'), JSON.stringify({ name: 'a-user-project', private: true, type: 'module' }));
  // The engines at the versions the repository's tests use (the packages'
  // peer ranges admit them); npm takes them from its cache when it has them.
  npm(['install', '--prefer-offline',
    ...NAMES.map((n) => join(dir, packed[n].filename)),
    `three@${pinned.three}`, `@babylonjs/core@${pinned['@babylonjs/core']}`, `@babylonjs/loaders@${pinned['@babylonjs/loaders']}`,
  ], project);
});

after(() => rmSync(dir, { recursive: true, force: true }));

/** Runs `code` as an ES module in the user's project; returns its JSON output. */
function inProject(code) {
  const file = join(dir, 'project', 'check.mjs');
  writeFileSync(file, code);
  return JSON.parse(execFileSync('node', [file], { cwd: join(dir, 'project'), encoding: 'utf8' }));
}

test('each tarball holds exactly the files its package.json lists', () => {
  for (const name of NAMES) {
    const manifest = JSON.parse(readFileSync(join(packagesDir, name, 'package.json'), 'utf8'));
    const files = packed[name].files.map((f) => f.path).sort();
    assert.deepEqual(files, [...manifest.files, 'package.json'].sort(), name);
    assert.equal(packed[name].name, name);
    assert.equal(packed[name].version, manifest.version);
    for (const entry of Object.values(manifest.exports)) assert.ok(files.includes(entry.slice(2)), `${name} exports ${entry}`);
    if (name !== 'aobake-contract') {
      assert.equal(manifest.dependencies['aobake-contract'], packed['aobake-contract'].version, `${name} depends on this contract`);
    }
  }
});

test('the project holds one copy of the contract and of each engine', () => {
  const nm = join(dir, 'project', 'node_modules');
  for (const name of [...NAMES, 'three', '@babylonjs/core', '@babylonjs/loaders']) {
    assert.ok(existsSync(join(nm, name, 'package.json')), name);
  }
  for (const importer of ['aobake-three', 'aobake-babylon']) {
    assert.ok(!existsSync(join(nm, importer, 'node_modules')), `${importer} has its own node_modules`);
  }
});

test('the contract: SH projections and the triple product against closed forms', () => {
  const got = inProject(`
    import { EXTENSION, basis9, extensionProblem, filterOf, gaunt, project, radianceProduct } from 'aobake-contract';
    import { basis16 } from 'aobake-contract/sh.js';
    let notExported = null;
    try { await import('aobake-contract/package.json'); } catch (e) { notExported = e.code; }
    const one = project(() => [1, 1, 1]);
    const zz = project(([, , z]) => [z * z, 0, 0]);
    const g = gaunt();
    let orth = 0;
    for (let i = 0; i < 16; i++) for (let k = 0; k < 16; k++) {
      orth = Math.max(orth, Math.abs(g[(i * 9) * 16 + k] - (i === k ? 0.282095 : 0)));
    }
    const p = radianceProduct([[1, 1, 1], ...Array(8).fill([0, 0, 0])]);
    console.log(JSON.stringify({
      EXTENSION, notExported,
      y: basis9([0.6, 0, 0.8]), y16: basis16([0, 0, 1])[12],
      one, zz: zz.map((c) => c[0]), orth,
      p00: p[0], p01: p[4], p1515: p[(15 * 16 + 15) * 4 + 1],
      bad: extensionProblem({ texCoord: -1 }, { textures: [] }),
      good: extensionProblem({ texCoord: 1, occlusion: { index: 0 }, sh: [{ index: 1 }, { index: 2 }, { index: 3 }], shScale: Array(9).fill(1), shOffset: Array(9).fill(0) }, { textures: [{}, {}, {}, {}] }),
      filter: filterOf({ filter: 'bicubic' }).filter, unknown: filterOf({ filter: 'lanczos' }).filter,
    }));
  `);
  assert.equal(got.EXTENSION, 'AOBAKE_lightmap');
  assert.equal(got.notExported, 'ERR_PACKAGE_PATH_NOT_EXPORTED');
  // Y at (0.6, 0, 0.8): 1/(2 sqrt(pi)), sqrt(3/(4 pi)) (y, z, x), ...
  const c1 = Math.sqrt(3 / (4 * Math.PI));
  const want = [1 / (2 * Math.sqrt(Math.PI)), 0, c1 * 0.8, c1 * 0.6, 0, 0,
    Math.sqrt(5 / (16 * Math.PI)) * (3 * 0.64 - 1), Math.sqrt(15 / (4 * Math.PI)) * 0.48, Math.sqrt(15 / (16 * Math.PI)) * 0.36];
  got.y.forEach((v, i) => assert.ok(Math.abs(v - want[i]) < 1e-5, `Y_${i}: ${v} against ${want[i]}`));
  // Y_3,0 at the pole: sqrt(7 / (4 pi)).
  assert.ok(Math.abs(got.y16 - Math.sqrt(7 / (4 * Math.PI))) < 1e-5);
  // A constant 1: only L_0 = sqrt(4 pi).
  assert.ok(Math.abs(got.one[0][0] - Math.sqrt(4 * Math.PI)) < 1e-5, `${got.one[0][0]}`);
  for (let k = 1; k < 9; k++) assert.ok(Math.abs(got.one[k][1]) < 1e-9, `L_${k}`);
  // z^2: L_0 = Y_00 4 pi / 3, L_6 = sqrt(5 / (16 pi)) 2 pi (6/5 - 2/3).
  assert.ok(Math.abs(got.zz[0] - (4 * Math.PI) / 3 / (2 * Math.sqrt(Math.PI))) < 1e-5);
  assert.ok(Math.abs(got.zz[6] - Math.sqrt(5 / (16 * Math.PI)) * 2 * Math.PI * (6 / 5 - 2 / 3)) < 1e-5);
  // Gamma_i0k = Y_00 delta_ik (orthonormality), and so P for L = Y_00's only.
  assert.ok(got.orth < 1e-6, `${got.orth}`);
  assert.ok(Math.abs(got.p00 - 0.282095) < 1e-6 && Math.abs(got.p01) < 1e-6 && Math.abs(got.p1515 - 0.282095) < 1e-6);
  assert.equal(got.bad, 'texCoord is not a set index');
  assert.equal(got.good, null);
  assert.equal(got.filter, 'bicubic');
  assert.equal(got.unknown, 'bilinear');
});

test('the importers load in the user\'s engines', () => {
  const got = inProject(`
    import { REVISION } from 'three';
    import { AobakeLightmapPlugin, AobakeLightmaps as ThreeLightmaps, EXTENSION } from 'aobake-three';
    import { registerAobakeLightmap, AobakeLightmaps } from 'aobake-babylon';
    import { registeredGLTFExtensions } from '@babylonjs/loaders/glTF/2.0/glTFLoaderExtensionRegistry.js';
    const before = registeredGLTFExtensions.has(EXTENSION);
    registerAobakeLightmap(new AobakeLightmaps());
    const plugin = new AobakeLightmapPlugin({ json: {} }, new ThreeLightmaps());
    console.log(JSON.stringify({ REVISION, before, after: registeredGLTFExtensions.has(EXTENSION), name: plugin.name }));
  `);
  assert.equal(got.REVISION, pinned.three.split('.')[1]);
  assert.equal(got.before, false);
  assert.equal(got.after, true, 'aobake-babylon registered into another copy of @babylonjs/loaders');
  assert.equal(got.name, 'AOBAKE_lightmap');
});

test('a bundle of both importers holds one contract and one of each engine', async () => {
  const project = join(dir, 'project');
  writeFileSync(join(project, 'entry.js'), `
    export { AobakeLightmapPlugin } from 'aobake-three';
    export { registerAobakeLightmap } from 'aobake-babylon';
  `);
  const out = await build({
    entryPoints: [join(project, 'entry.js')], absWorkingDir: project, bundle: true, format: 'esm',
    write: false, metafile: true, logLevel: 'error',
  });
  const inputs = Object.keys(out.metafile.inputs);
  const count = (suffix) => inputs.filter((p) => p.endsWith(suffix)).length;
  assert.equal(count('aobake-contract/extension.js'), 1);
  assert.equal(count('aobake-contract/sh.js'), 1);
  assert.equal(count('three/build/three.core.js'), 1);
  assert.equal(count('@babylonjs/core/Materials/materialPluginBase.js'), 1);
  assert.ok(inputs.every((p) => p.startsWith('node_modules/') || p === 'entry.js'), inputs.find((p) => !p.startsWith('node_modules/')));
});
