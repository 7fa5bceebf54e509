// Validate a glTF 2.0 file (.glb or .gltf) with the Khronos glTF validator and print its JSON report.
//
//   node tests/gltf_validate.mjs FILE
//
// The validator is the npm package gltf-validator, installed by .ci/run into .ci/gltf-validator
// (or set GLTF_VALIDATOR to the package's folder). Exit status: 0 no errors, 1 errors (the report
// says which), 2 the validator or the file could not be loaded.
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";
import { fileURLToPath } from "node:url";

const INSTALL = "npm install --no-audit --no-fund --prefix .ci/gltf-validator gltf-validator@2.0.0-dev.3.10";
const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..");
const where = process.env.GLTF_VALIDATOR || path.join(root, ".ci", "gltf-validator", "node_modules", "gltf-validator");

let validator;
try {
  validator = createRequire(import.meta.url)(where);
} catch (e) {
  console.error(`the Khronos glTF validator is not installed at ${where}; install it with: ${INSTALL}`);
  process.exit(2);
}
const file = process.argv[2];
if (!file) {
  console.error("usage: node tests/gltf_validate.mjs FILE.glb");
  process.exit(2);
}
let data;
try {
  data = new Uint8Array(readFileSync(file));
} catch (e) {
  console.error(`${file}: cannot read: ${e.message}`);
  process.exit(2);
}
try {
  const report = await validator.validateBytes(data, { uri: path.basename(file), maxIssues: 0, writeTimestamp: false });
  report.validatorVersion = validator.version();
  console.log(JSON.stringify(report, null, 2));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
} catch (e) {
  console.error(`${file}: the validator could not read it: ${e}`);
  process.exit(2);
}
