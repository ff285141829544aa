// Usage: node validate.mjs FILE.glb [...]
// Prints one JSON line per file: {file, errors, warnings, messages: [code: message @ pointer]}.
// Exits 1 if any file has validation errors.
import { readFile } from 'node:fs/promises';
import validator from 'gltf-validator';

let failed = false;
for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, {
    maxIssues: 200,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not read')),
  });
  const issues = report.issues;
  const messages = issues.messages
    .filter((m) => m.severity <= 1)
    .map((m) => `${m.severity === 0 ? 'E' : 'W'} ${m.code}: ${m.message} @ ${m.pointer ?? ''}`);
  console.log(JSON.stringify({ file, errors: issues.numErrors, warnings: issues.numWarnings, messages }));
  if (issues.numErrors > 0) failed = true;
}
process.exit(failed ? 1 : 0);
