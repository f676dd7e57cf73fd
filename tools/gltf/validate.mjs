// Validate GLB files with the Khronos glTF validator; prints one JSON line per file:
//   {"file": ..., "errors": n, "warnings": n, "messages": [first few issues]}
// Exit code 1 if any file has errors. Usage: node validate.mjs a.glb b.glb ...
import { readFile } from "node:fs/promises";
import validator from "gltf-validator";

let failed = false;
for (const file of process.argv.slice(2)) {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, { maxIssues: 50 });
  const issues = report.issues;
  const messages = issues.messages.filter((m) => m.severity <= 1).slice(0, 5)
    .map((m) => `${m.code}: ${m.message} (${m.pointer ?? ""})`);
  if (issues.numErrors > 0) failed = true;
  console.log(JSON.stringify({ file, errors: issues.numErrors, warnings: issues.numWarnings, messages }));
}
process.exit(failed ? 1 : 0);
