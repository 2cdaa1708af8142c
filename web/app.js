// The page: controls → options (the command line's names) → the worker → canvases.
const $ = (id) => document.getElementById(id);
const form = $("controls");
const worker = new Worker(new URL("./worker.js", import.meta.url), { type: "module" });

// Images larger than this are refused from their header: the tab's memory is the limit.
// The library counts bytes a pixel decoded against it: a 24 MP RGB JPEG needs 72 MP worth.
const MAX_PIXELS = 150_000_000;

const state = {
  name: "image.png", loaded: false, busy: false, pending: false, nextId: 1,
  last: null, lastCompare: null, downloads: new Map(), firstRender: null, loadStart: 0,
};
// For the browser test and for scripting from the console.
window.halftonePage = state;

function status(text, error = false) {
  const s = $("status");
  s.textContent = text;
  s.classList.toggle("error", error);
}

// ---- listings ----------------------------------------------------------------------
// Adds an option a name; `chosen` is the one a reset of the form goes back to.
function fill(select, names, chosen) {
  for (const n of names) {
    const o = document.createElement("option");
    o.value = o.textContent = n;
    if (n === chosen) o.defaultSelected = o.selected = true;
    select.append(o);
  }
}

worker.postMessage({ type: "listings" });

// ---- options ------------------------------------------------------------------------
// The command line's defaults: a control at its default is left off the command line.
const DEFAULTS = {
  method: "diffuse", kernel: "floyd-steinberg", levels: "2", threshold: "0.5", cell: "fit",
  lpi: "106", angle: "45", spot: "Round", color: "gray", press: "fogra39", gcr: "50", tac: "300",
  content: "photo", "dot-gain": "0", gamma: "1", "zpl-encoding": "hex",
};
// Controls that matter only for some methods or colours.
const ONLY = {
  kernel: (o) => o.method === "diffuse", palette: (o) => o.method === "diffuse",
  serpentine: (o) => o.method === "diffuse",
  mask: (o) => o.method === "pattern" || o.method === "ordered", cell: (o) => o.method === "pattern",
  threshold: (o) => o.method === "threshold",
  lpi: (o) => o.method === "screen" || o.color === "cmyk", spot: (o) => o.method === "screen" || o.color === "cmyk",
  angle: (o) => o.method === "screen" && o.color !== "cmyk",
  press: (o) => o.color === "cmyk", gcr: (o) => o.color === "cmyk", tac: (o) => o.color === "cmyk",
};

function options() {
  const raw = {};
  for (const el of form.elements) {
    if (!el.name) continue;
    raw[el.name] = el.type === "checkbox" ? el.checked : el.value.trim();
  }
  const o = {};
  for (const [k, v] of Object.entries(raw)) {
    if (ONLY[k] && !ONLY[k](raw)) continue;
    if (k === "serpentine") { if (!v) o["no-serpentine"] = true; continue; }
    if (v === "" || v === false) continue;
    if (DEFAULTS[k] !== undefined && String(v) === DEFAULTS[k]) continue;
    o[k] = v;
  }
  if (o.color === "cmyk" && $("plate").value === "preview") o.preview = true;
  return o;
}

function shellQuote(s) {
  return /^[A-Za-z0-9_./:=%,+-]+$/.test(s) ? s : "'" + s.replace(/'/g, "'\\''") + "'";
}

const EXT = { tiff: "tif" };
function commandLine(o, format) {
  const base = state.name.replace(/\.[^.]*$/, "") || "image";
  const args = ["halftone", "convert", shellQuote(state.name), "-o", shellQuote(`${base}-halftone.${EXT[format] || format}`)];
  // A preset's own format wins over the name's extension unless --format says otherwise.
  const presetFormat = o.preset && (state.listings?.presets || []).find((p) => p.name === o.preset)?.format;
  if (presetFormat && presetFormat !== format) args.push("--format", format);
  for (const [k, v] of Object.entries(o)) {
    if (k === "preview") { args.push("--preview", shellQuote(`${base}-halftone-preview.png`)); continue; }
    if (v === true) args.push(`--${k}`);
    else args.push(`--${k}`, shellQuote(String(v)));
  }
  return args.join(" ");
}
window.halftoneCommandLine = commandLine;

// ---- rendering ----------------------------------------------------------------------
function showControls() {
  const raw = { method: form.method.value, color: form.color.value };
  for (const label of form.querySelectorAll("label[data-for]")) {
    const wants = label.dataset.for.split(" ");
    label.classList.toggle("hidden", !wants.includes(raw.method) && !wants.includes(raw.color));
  }
  const hide = (name, show) => form.elements[name].closest("label").classList.toggle("hidden", !show);
  hide("angle", raw.method === "screen" && raw.color !== "cmyk");
}

function render() {
  showControls();
  if (!state.loaded) return;
  if (state.busy) { state.pending = true; return; }
  state.busy = true;
  state.pending = false;
  const o = options();
  const id = state.nextId++;
  state.current = { id, options: o, format: preferredFormat(o) };
  $("command").textContent = commandLine(o, state.current.format);
  worker.postMessage({
    type: "render", id, options: o, view: o.color === "cmyk" ? $("plate").value : "composite",
    compare: o.color === "cmyk" ? null : { dpi: Number(o.dpi) || 300, distance: 12 },
  });
}

function preferredFormat(o) {
  if (o.preset) {
    const p = (state.listings?.presets || []).find((x) => x.name === o.preset);
    if (p && p.format) return p.format;
  }
  return "png";
}

function draw(canvas, width, height, rgba) {
  canvas.width = width;
  canvas.height = height;
  canvas.getContext("2d").putImageData(new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, width * height * 4), width, height), 0, 0);
  layout();
}

function layout() {
  const z = Number($("zoom").value);
  const h = $("halftone"), og = $("original");
  const split = $("layout").value === "split";
  $("stage").className = split ? "split" : "side";
  $("splitlabel").classList.toggle("hidden", !split);
  h.style.width = `${h.width * z}px`;
  h.style.height = `${h.height * z}px`;
  // In the split view the original is laid over the halftone at the halftone's size.
  const ow = split && h.width ? h.width : og.width, oh = split && h.width ? h.height : og.height;
  og.style.width = `${ow * z}px`;
  og.style.height = `${oh * z}px`;
  $("orig-pane").style.width = split ? `${(ow * z * $("split").value) / 100}px` : "";
}

worker.onmessage = (ev) => {
  const m = ev.data;
  if (m.type === "listings") {
    const l = (state.listings = m.listings);
    fill($("method"), l.methods, "diffuse");
    fill($("kernel"), l.kernels, "floyd-steinberg");
    fill($("palette"), l.palettes);
    fill($("mask"), l.masks);
    fill($("spot"), l.spots, "Round");
    fill($("color"), l.colors, "gray");
    fill($("content"), l.contents, "photo");
    for (const p of l.presets) {
      const o = document.createElement("option");
      o.value = p.name;
      o.textContent = p.name;
      o.title = p.description || "";
      $("preset").append(o);
    }
    for (const f of l.formats) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = f.toUpperCase();
      b.dataset.format = f;
      b.onclick = () => download(f);
      $("formats").append(b);
    }
    showControls();
    state.ready = true;
  } else if (m.type === "loaded") {
    state.loaded = true;
    state.loads = (state.loads || 0) + 1;
    state.name = m.name;
    draw($("original"), m.width, m.height, m.rgba);
    status(`${m.name}: ${m.width}×${m.height}, decoded in ${m.ms.toFixed(0)} ms`);
    render();
  } else if (m.type === "rendered") {
    draw($("halftone"), m.width, m.height, m.rgba);
    if (state.firstRender === null) state.firstRender = performance.now() - state.loadStart;
    state.last = { id: m.id, convertMs: m.convertMs, totalMs: m.totalMs, width: m.width, height: m.height };
    $("timing").textContent = `${m.width}×${m.height}, ${m.levels} levels × ${m.planes} plane${m.planes > 1 ? "s" : ""}: halftoned in ${m.convertMs.toFixed(1)} ms (${m.totalMs.toFixed(1)} ms with display)`;
    status(`${state.name}: ready`);
    finish();
  } else if (m.type === "compared") {
    state.lastCompare = m;
    const body = $("quality").tBodies[0];
    body.replaceChildren();
    const row = (k, v) => { const tr = body.insertRow(); tr.insertCell().textContent = k; tr.insertCell().textContent = v; };
    if (m.figures) {
      const f = m.figures, n = (x, d = 2) => (x === null ? "∞" : Number(x).toFixed(d));
      row("HVS PSNR", `${n(f.hvs_psnr_db)} dB`);
      row("tone bias", n(f.tone_bias, 4));
      row("L* RMS", n(f.lstar_rms));
      row("plain PSNR", `${n(f.plain_psnr_db)} dB`);
      row("measured in", `${m.ms.toFixed(0)} ms`);
    } else row("compare", m.error);
  } else if (m.type === "files") {
    const base = state.name.replace(/\.[^.]*$/, "") || "image";
    for (const f of m.files) {
      const ext = f.suffix === "-preview" ? "png" : EXT[m.format] || m.format;
      save(`${base}-halftone${f.suffix}.${ext}`, f.bytes);
    }
    state.downloads.set(m.id, m.files.length);
  } else if (m.type === "error") {
    status(m.message, true);
    state.errors = (state.errors || 0) + 1;
    if (m.id && state.current && m.id === state.current.id) finish();
  }
};

function finish() {
  state.busy = false;
  state.rendered = state.current?.id;
  if (state.pending) render();
}

function save(name, bytes) {
  const url = URL.createObjectURL(new Blob([bytes], { type: "application/octet-stream" }));
  const a = document.createElement("a");
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

function download(format) {
  const o = options();
  $("command").textContent = commandLine(o, format);
  worker.postMessage({ type: "encode", id: state.nextId++, format, preview: !!o.preview });
}

// ---- input --------------------------------------------------------------------------
async function load(file) {
  if (!file) return;
  status(`reading ${file.name}…`);
  state.loadStart = performance.now();
  state.firstRender = null;
  const bytes = await file.arrayBuffer();
  worker.postMessage({ type: "load", id: state.nextId++, name: file.name || "pasted.png", bytes, maxPixels: MAX_PIXELS }, [bytes]);
}

$("file").addEventListener("change", (e) => load(e.target.files[0]));
document.addEventListener("dragover", (e) => { e.preventDefault(); document.body.classList.add("dragging"); });
document.addEventListener("dragleave", () => document.body.classList.remove("dragging"));
document.addEventListener("drop", (e) => {
  e.preventDefault();
  document.body.classList.remove("dragging");
  load(e.dataTransfer.files[0]);
});
document.addEventListener("paste", (e) => {
  const item = [...e.clipboardData.items].find((i) => i.kind === "file");
  if (item) load(item.getAsFile());
});
form.addEventListener("input", render);
form.addEventListener("change", render);
form.addEventListener("submit", (e) => e.preventDefault());
$("plate").addEventListener("change", render);
for (const id of ["zoom", "layout", "split"]) $(id).addEventListener("input", layout);
