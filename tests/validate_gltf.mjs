// Validates one glTF file with the Khronos glTF validator (npm `gltf-validator`, which `.ci/deps`
// installs into target/gltf-validator) and prints its JSON report. Usage: node validate_gltf.mjs FILE
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';

const require = createRequire(import.meta.url);
const validator = require(path.resolve('target/gltf-validator/node_modules/gltf-validator'));
const file = process.argv[2];
const bytes = new Uint8Array(await readFile(file));
const report = await validator.validateBytes(bytes, {
  uri: path.basename(file),
  maxIssues: 100,
  externalResourceFunction: (uri) =>
    readFile(path.join(path.dirname(file), decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
});
console.log(JSON.stringify(report));
