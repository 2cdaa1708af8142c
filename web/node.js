// The package's entry in Node (18 and later): the WebAssembly module is read from the
// package's folder and instantiated on import, so every export is ready to call. Bundlers
// and browsers take pkg/halftone_web.js instead, whose default export `init()` fetches the
// .wasm next to it.
import { readFileSync } from "node:fs";
import { initSync } from "./pkg/halftone_web.js";

initSync({ module: readFileSync(new URL("./pkg/halftone_web_bg.wasm", import.meta.url)) });

export * from "./pkg/halftone_web.js";
export { default } from "./pkg/halftone_web.js";
