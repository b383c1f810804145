// Offline schema check of Kubernetes manifests: every YAML document is validated against the
// JSON schema kubernetes-models bundles for its apiVersion and kind (infra.md section 3). It
// catches wrong types and missing required fields, not misspelt optional ones (the schemas allow
// extra fields): kubectl kustomize's render is the other half of the check.
// usage: node k8s_validate.js FILE...   (FILE "-" reads standard input)
'use strict';
const fs = require('fs');
const yaml = require('js-yaml');

function modelClass(apiVersion, kind) {
  // "apps/v1" -> kubernetes-models/apps/v1/Deployment; "v1" -> kubernetes-models/v1/Service
  const parts = apiVersion.split('/');
  const module = ['kubernetes-models', ...parts, kind].join('/');
  return require(module)[kind];
}

let passed = 0;
let failed = 0;
for (const file of process.argv.slice(2)) {
  const text = fs.readFileSync(file === '-' ? 0 : file, 'utf8');
  let docs;
  try {
    docs = yaml.loadAll(text);
  } catch (e) {
    console.error(`FAIL ${file}: not YAML: ${e.message}`);
    failed++;
    continue;
  }
  for (const doc of docs) {
    if (doc === null || doc === undefined) continue;
    const name = `${file}: ${doc.kind}/${doc.metadata && doc.metadata.name}`;
    if (typeof doc.apiVersion !== 'string' || typeof doc.kind !== 'string') {
      console.error(`FAIL ${name}: no apiVersion or kind`);
      failed++;
      continue;
    }
    let Model;
    try {
      Model = modelClass(doc.apiVersion, doc.kind);
    } catch (e) {
      Model = undefined;
    }
    if (typeof Model !== 'function') {
      console.error(`FAIL ${name}: no schema for ${doc.apiVersion} ${doc.kind}`);
      failed++;
      continue;
    }
    try {
      new Model(doc).validate();
      console.log(`ok   ${name}`);
      passed++;
    } catch (e) {
      console.error(`FAIL ${name}: ${e.message}`);
      failed++;
    }
  }
}
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed > 0 || passed === 0 ? 1 : 0);
