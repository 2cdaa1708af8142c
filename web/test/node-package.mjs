// The npm package as its users get it: run from a folder where `npm install` put the
// `npm pack` tarball (scripts/release.sh --ci copies this file there), it imports
// `halftone-web` by name (Node's entry, no DOM), converts pictures to several formats and
// checks each file byte for byte against the command line's.
//
// node node-package.mjs REPO_ROOT HALFTONE_BINARY
// Prints one line a case and `npm package: N passed, M failed`; exits 1 on any failure.
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { Source, convert, listings } from "halftone-web";

const [root, cli] = process.argv.slice(2);
if (!root || !cli) {
  console.log("usage: node node-package.mjs REPO_ROOT HALFTONE_BINARY");
  process.exit(2);
}
const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "halftone-npm-"));
let passed = 0;
let failed = 0;

// [input, output extension, options (the page's JSON), the command line's flags]
const cases = [
  ["samples/kd-series.png", "pbm", {}, []],
  ["samples/raytrace.png", "png", { method: "ordered", mask: "bayer-8", levels: "4", width: "200" },
    ["--method", "ordered", "--mask", "bayer-8", "--levels", "4", "--width", "200"]],
  ["samples/color-balls.png", "png", { device: "spectra6-7in3-v2" }, ["--device", "spectra6-7in3-v2"]],
  ["samples/warn-studio.png", "escpos", { preset: "thermal-80mm" }, ["--preset", "thermal-80mm"]],
  ["tests/golden/inputs/rgb16.tif", "pdf", { color: "cmyk", dpi: "300" }, ["--color", "cmyk", "--dpi", "300"]],
  ["tests/golden/inputs/grey16.pgm", "zpl", { method: "screen", lpi: "40", dpi: "203" },
    ["--method", "screen", "--lpi", "40", "--dpi", "203"]],
];

for (const [input, ext, options, flags] of cases) {
  const name = `${path.basename(input)} -> ${ext} ${flags.join(" ")}`;
  try {
    const bytes = fs.readFileSync(path.join(root, input));
    const rendered = convert(bytes, JSON.stringify({ ...options, format: ext }));
    const ours = rendered.encode(ext);
    const out = path.join(tmp, `cli.${ext}`);
    execFileSync(cli, ["convert", path.join(root, input), "-o", out, ...flags], { stdio: "pipe" });
    const theirs = fs.readFileSync(out);
    if (Buffer.compare(Buffer.from(ours), theirs) === 0) {
      passed++;
      console.log(`ok   ${name} (${theirs.length} bytes)`);
    } else {
      failed++;
      console.log(`FAIL ${name}: ${ours.length} bytes against the command line's ${theirs.length}`);
    }
  } catch (e) {
    failed++;
    console.log(`FAIL ${name}: ${e.message ?? e}`);
  }
}

// A decoded source converted twice, the listings, and a file that is not an image.
try {
  const src = new Source(fs.readFileSync(path.join(root, "samples/raytrace.png")), 150e6);
  const a = src.convert("{}").encode("pbm");
  const b = convert(fs.readFileSync(path.join(root, "samples/raytrace.png")), "{}").encode("pbm");
  if (src.width !== 320 || src.height !== 240 || Buffer.compare(Buffer.from(a), Buffer.from(b)) !== 0) {
    throw new Error(`Source: ${src.width}x${src.height}, ${a.length} against ${b.length} bytes`);
  }
  const methods = JSON.parse(listings()).methods;
  if (!Array.isArray(methods) || methods.length < 5) throw new Error("listings: no methods");
  passed++;
  console.log("ok   Source, listings");
} catch (e) {
  failed++;
  console.log(`FAIL Source, listings: ${e.message ?? e}`);
}
try {
  convert(new TextEncoder().encode("not an image"), "{}");
  failed++;
  console.log("FAIL a text file: no error");
} catch (e) {
  passed++;
  console.log(`ok   a text file refused: ${e.message ?? e}`);
}

fs.rmSync(tmp, { recursive: true, force: true });
console.log(`npm package: ${passed} passed, ${failed} failed`);
process.exit(failed === 0 ? 0 : 1);
