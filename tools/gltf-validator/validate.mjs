// Validate glTF / GLB files with the Khronos glTF-Validator and print one JSON report per file.
//
//   node tools/gltf-validator/validate.mjs FILE...
//
// Each line of stdout is one JSON object: {file, numErrors, numWarnings, numInfos, numHints,
// messages: [{code, severity, message, pointer}], info} (severity 0 error, 1 warning, 2 info,
// 3 hint). External resources (buffers, images) are read from disk relative to the file. A file
// that cannot be read or parsed gets numErrors 1 and a message with code "UNREADABLE".
// Exit code: 0 when every file has 0 errors and 0 warnings, 1 otherwise, 2 without files.
import { readFile } from "node:fs/promises";
import path from "node:path";
import validator from "gltf-validator";

const SEVERITY = ["error", "warning", "info", "hint"];

/** Read an external resource named by `uri` beside `file`. */
function resourceReader(file) {
  return (uri) => readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)));
}

/** The validator's report of one file, reduced to the figures and messages the tests use. */
async function validate(file) {
  try {
    const bytes = new Uint8Array(await readFile(file));
    const report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0,
      externalResourceFunction: resourceReader(file),
    });
    const issues = report.issues;
    return {
      file,
      numErrors: issues.numErrors,
      numWarnings: issues.numWarnings,
      numInfos: issues.numInfos,
      numHints: issues.numHints,
      messages: issues.messages.map((m) => ({
        code: m.code,
        severity: SEVERITY[m.severity] ?? String(m.severity),
        message: m.message,
        pointer: m.pointer ?? null,
      })),
      info: report.info ?? null,
    };
  } catch (error) {
    const message = String(error && error.message ? error.message : error);
    return {
      file, numErrors: 1, numWarnings: 0, numInfos: 0, numHints: 0,
      messages: [{ code: "UNREADABLE", severity: "error", message, pointer: null }], info: null,
    };
  }
}

const files = process.argv.slice(2);
if (files.length === 0) {
  process.stderr.write("usage: node validate.mjs FILE.glb|FILE.gltf...\n");
  process.exit(2);
}
let clean = true;
for (const file of files) {
  const report = await validate(file);
  clean &&= report.numErrors === 0 && report.numWarnings === 0;
  process.stdout.write(JSON.stringify(report) + "\n");
}
process.exit(clean ? 0 : 1);
