// Khronos' glTF validator over each file named on the command line: one JSON line per file
// with its issue counts and messages (`node validate.mjs a.glb b.glb`).
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';

const require = createRequire(process.env.TROUPE_NPM_MODULES + '/');
const validator = require('gltf-validator');

for (const path of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(path));
  const report = await validator.validateBytes(bytes, { maxIssues: 100 });
  const issues = report.issues;
  console.log(JSON.stringify({
    file: path,
    validator: report.validatorVersion,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    hints: issues.numHints,
    messages: issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer ?? ''}: ${m.message}`),
    info: report.info ? { animations: report.info.animationCount, skins: report.info.hasSkins,
      nodes: report.info.nodeCount, primitives: report.info.totalTriangleCount } : null,
  }));
}
