#!/usr/bin/env node
// Validates a glTF 2.0 asset (.glb or .gltf) with the Khronos glTF validator
// (npm package gltf-validator, a JS library compiled from the Dart validator) and prints
// the report's counts. Exit status: 0 no errors, 1 errors (the messages are printed),
// 2 usage or unreadable file, 77 the validator is not installed (ctest's "skipped").
//
//   node tools/gltf-validate.js FILE [--json]
//
// The module is looked up in: $SPECULA_GLTF_VALIDATOR_PATHS (':'-separated node_modules
// folders), node's own resolution (NODE_PATH, ./node_modules), then npm's global root.
// tools/install-deps.sh installs it globally (npm install -g gltf-validator@2.0.0-dev.3.10).
'use strict';
const fs = require('fs');
const path = require('path');

function loadValidator() {
    const dirs = (process.env.SPECULA_GLTF_VALIDATOR_PATHS || '').split(':').filter(Boolean);
    for (const dir of dirs) {
        try { return require(path.join(path.resolve(dir), 'gltf-validator')); } catch (e) { /* next */ }
    }
    try { return require('gltf-validator'); } catch (e) { /* next */ }
    const globalRoots = [];
    try {
        globalRoots.push(require('child_process').execSync('npm root -g', { stdio: ['ignore', 'pipe', 'ignore'] })
            .toString().trim());
    } catch (e) { /* no npm */ }
    globalRoots.push('/usr/local/lib/node_modules', '/usr/lib/node_modules');
    for (const root of globalRoots) {
        try { return require(path.join(root, 'gltf-validator')); } catch (e) { /* next */ }
    }
    return null;
}

async function main() {
    const args = process.argv.slice(2);
    const asJson = args.includes('--json');
    const files = args.filter((a) => a !== '--json');
    if (files.length !== 1) {
        console.error('usage: node tools/gltf-validate.js FILE [--json]');
        return 2;
    }
    const validator = loadValidator();
    if (!validator) {
        console.error('gltf-validate: the gltf-validator npm package is not installed ' +
                      '(tools/install-deps.sh installs it: npm install -g gltf-validator@2.0.0-dev.3.10)');
        return 77;
    }
    const file = files[0];
    let data;
    try {
        data = new Uint8Array(fs.readFileSync(file));
    } catch (e) {
        console.error(`gltf-validate: ${file}: ${e.message}`);
        return 2;
    }
    const dir = path.dirname(path.resolve(file));
    const report = await validator.validateBytes(data, {
        uri: path.basename(file),
        maxIssues: 0, // all of them
        externalResourceFunction: (uri) => new Promise((resolve, reject) => {
            fs.readFile(path.join(dir, decodeURIComponent(uri)), (err, bytes) => {
                if (err) reject(err.toString()); else resolve(new Uint8Array(bytes));
            });
        }),
    });
    const issues = report.issues;
    if (asJson) {
        console.log(JSON.stringify(report, null, 2));
    } else {
        console.log(`${file}: validator ${report.validatorVersion}: ` +
                    `${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
                    `${issues.numInfos} infos, ${issues.numHints} hints`);
        for (const m of issues.messages) {
            const severity = ['error', 'warning', 'info', 'hint'][m.severity] || String(m.severity);
            console.log(`  ${severity}: ${m.code}: ${m.message}${m.pointer ? ` (${m.pointer})` : ''}`);
        }
    }
    return issues.numErrors > 0 ? 1 : 0;
}

main().then((code) => process.exit(code), (err) => {
    console.error(`gltf-validate: ${err && err.message ? err.message : err}`);
    process.exit(2);
});
