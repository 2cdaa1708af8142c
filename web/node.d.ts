// Node's entry (node.js): the same exports as pkg/halftone_web.js, already initialised.
export * from "./pkg/halftone_web.js";
export { default } from "./pkg/halftone_web.js";
