// The Khronos glTF-Validator over each file named: one JSON line per file with every message
// (code, severity 0 error .. 3 hint, pointer). Run by tests/integration/bake/clients.rs;
// `npm ci --prefix tests/gltf-validator` installs it.
import { readFile } from 'node:fs/promises';
import path from 'node:path';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0,
    writeTimestamp: false,
    externalResourceFunction: (uri) => readFile(path.resolve(path.dirname(file), decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
  });
  const messages = report.issues.messages.map((m) => ({ code: m.code, severity: m.severity, pointer: m.pointer ?? null, message: m.message }));
  console.log(JSON.stringify({ file, validator: report.validatorVersion, messages }));
}
