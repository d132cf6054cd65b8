// Runs the Khronos glTF-Validator (npm `gltf-validator`) over .glb/.gltf files and directories
// (searched recursively). Exits non-zero when any file has an error, or a warning about skin
// weights/joints or accessor data and bounds (ARCHITECTURE.md: exported files pass with zero
// errors and no such warnings). Other warnings and infos are printed, not fatal.
//
// Usage: node tools/gltf-validator/validate.mjs FILE_OR_DIR...   (after `npm ci` in this folder)
import fs from "node:fs";
import path from "node:path";
import validator from "gltf-validator";

function collect(p, out) {
  const st = fs.statSync(p);
  if (st.isDirectory()) {
    for (const e of fs.readdirSync(p).sort()) collect(path.join(p, e), out);
  } else if (/\.(glb|gltf)$/i.test(p)) {
    out.push(p);
  }
}

// Warnings that mean the exported numbers are wrong, not merely unusual.
const FATAL_WARNING = /WEIGHT|JOINT|^ACCESSOR_/;

const args = process.argv.slice(2);
if (args.length === 0) {
  console.error("usage: node validate.mjs FILE_OR_DIR...");
  process.exit(2);
}
const files = [];
for (const a of args) collect(a, files);
if (files.length === 0) {
  console.error(`no .glb or .gltf files under ${args.join(", ")}`);
  process.exit(2);
}

let failed = 0;
for (const file of files) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  let report;
  try {
    report = await validator.validateBytes(bytes, {
      uri: path.basename(file),
      maxIssues: 0,
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          const p = path.resolve(path.dirname(file), decodeURIComponent(uri));
          fs.readFile(p, (err, data) => (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
        }),
    });
  } catch (e) {
    console.error(`FAIL ${file}: the validator could not read it: ${e}`);
    failed++;
    continue;
  }
  const issues = report.issues;
  const fatal = issues.messages.filter(
    (m) => m.severity === 0 || (m.severity === 1 && FATAL_WARNING.test(m.code)),
  );
  const status = fatal.length > 0 ? "FAIL" : "ok  ";
  console.log(
    `${status} ${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ` +
      `${issues.numInfos} infos (${report.info?.totalTriangleCount ?? "?"} triangles)`,
  );
  for (const m of issues.messages.filter((m) => m.severity <= 1)) {
    const kind = m.severity === 0 ? "error" : "warning";
    console.log(`    ${kind} ${m.code} at ${m.pointer ?? "?"}: ${m.message}`);
  }
  if (fatal.length > 0) failed++;
}
console.log(`glTF-Validator ${validator.version()}: ${files.length - failed} of ${files.length} files pass`);
process.exit(failed > 0 ? 1 : 0);
