// Validate glTF/GLB files with the Khronos glTF-Validator; print one JSON array of reports
// ({path, errors, warnings, infos, hints, messages: [{code, severity, pointer, message}]}).
// Usage: node validate.js FILE...
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function validate(file) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 200,
    externalResourceFunction: (uri) => Promise.reject(new Error(`external resource ${uri}`)),
  });
  const issues = report.issues;
  return {
    path: file,
    errors: issues.numErrors,
    warnings: issues.numWarnings,
    infos: issues.numInfos,
    hints: issues.numHints,
    messages: issues.messages.map((m) => ({code: m.code, severity: m.severity, pointer: m.pointer, message: m.message})),
  };
}

(async () => {
  const reports = [];
  for (const file of process.argv.slice(2)) reports.push(await validate(file));
  process.stdout.write(JSON.stringify(reports));
})().catch((err) => { console.error(String(err)); process.exit(1); });
