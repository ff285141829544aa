// Builds the Babylon.js bundle `aobake view` serves (viewer-entry.js:
// Babylon.js 9.28.0 as pinned, and the package aobake-babylon) into
// viewer/vendor/babylon/aobake-babylon.js.gz, or with --check verifies that
// the committed file is what this checkout builds (babylon.test.mjs runs
// the check, so the bundle cannot fall behind the importer).
//
// Run: node babylon/build-viewer.mjs [--check]   (after npm ci in the repository's root)

import { build } from 'esbuild';
import { gunzipSync, gzipSync, constants } from 'node:zlib';
import { mkdirSync, readFileSync, writeFileSync, copyFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
export const bundlePath = join(here, '../viewer/vendor/babylon/aobake-babylon.js.gz');

/** The bundle's bytes (minified ES module), as this checkout builds it. */
export async function bundle() {
  const out = await build({
    entryPoints: [join(here, 'viewer-entry.js')], bundle: true, format: 'esm', minify: true,
    write: false, logLevel: 'error', legalComments: 'none', target: 'es2020',
  });
  return Buffer.from(out.outputFiles[0].contents);
}

/** null if the committed bundle is this checkout's, else why not. */
export async function check() {
  const want = await bundle();
  let have;
  try {
    have = gunzipSync(readFileSync(bundlePath));
  } catch (e) {
    return `${bundlePath} does not read (${e.message}); run node babylon/build-viewer.mjs`;
  }
  return have.equals(want) ? null
    : `${bundlePath} is not what this checkout builds (${have.length} against ${want.length} bytes); run node babylon/build-viewer.mjs`;
}

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  if (process.argv.includes('--check')) {
    const problem = await check();
    if (problem) {
      console.error(problem);
      process.exit(1);
    }
  } else {
    const js = await bundle();
    mkdirSync(dirname(bundlePath), { recursive: true });
    writeFileSync(bundlePath, gzipSync(js, { level: constants.Z_BEST_COMPRESSION }));
    copyFileSync(join(here, '../node_modules/@babylonjs/core/license.md'), join(dirname(bundlePath), 'LICENSE'));
    console.log(`${bundlePath}: ${js.length} bytes, gzip ${readFileSync(bundlePath).length}`);
  }
}
