#!/usr/bin/env node
// Validates glTF/GLB files with the Khronos glTF validator and prints one
// JSON report per file (an array). Exit code 0 when every file has zero
// errors, 1 otherwise, 2 on a usage or I/O problem.
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function main(files) {
  if (files.length === 0) {
    console.error('usage: validate-gltf.js FILE.glb|FILE.gltf ...');
    return 2;
  }
  const reports = [];
  for (const file of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: file,
      maxIssues: 100,
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
            err ? reject(err.toString()) : resolve(new Uint8Array(data)));
        }),
    });
    reports.push(report);
  }
  console.log(JSON.stringify(reports, null, 2));
  return reports.every((r) => r.issues.numErrors === 0) ? 0 : 1;
}

// exitCode, not exit(): exit() would cut a long report short on a pipe.
main(process.argv.slice(2)).then(
  (code) => {
    process.exitCode = code;
  },
  (err) => {
    console.error(`validate-gltf: ${err}`);
    process.exit(2);
  },
);
