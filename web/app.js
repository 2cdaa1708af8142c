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
  intent: "perceptual", exposure: "0", saturation: "1", tone: "auto", gamut: "auto", "ink-colours": "measured",
};
// With a device: its inks are the palette, so palette, colour and levels are not asked for;
// intent and its steering are asked for only then (tone and gamut steer the perceptual intent).
const withDevice = (o) => !!o.device;
const perceptual = (o) => withDevice(o) && o.intent === "perceptual";
// Controls that matter only for some methods or colours.
const ONLY = {
  kernel: (o) => o.method === "diffuse", palette: (o) => o.method === "diffuse" && !withDevice(o),
  color: (o) => !withDevice(o), levels: (o) => !withDevice(o),
  intent: withDevice, exposure: withDevice, saturation: withDevice, "ink-colours": withDevice,
  tone: perceptual, gamut: perceptual,
  // A fit mode needs a box: --fit, or a device's panel when no size is given.
  "fit-mode": (o) => !!o.fit || (withDevice(o) && !o.width && !o.height),
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
function device() {
  return (state.listings?.devices || []).find((d) => d.name === form.device.value) || null;
}

function showControls() {
  const d = device();
  const raw = { method: form.method.value, color: d ? "rgb" : form.color.value, device: d?.name, intent: form.intent.value };
  for (const label of form.querySelectorAll("label[data-for], label[data-device], label[data-no-device]")) {
    const wants = label.dataset.for ? label.dataset.for.split(" ") : null;
    const hidden = (wants && !wants.includes(raw.method) && !wants.includes(raw.color))
      || (label.dataset.device !== undefined && !d)
      || (label.dataset.perceptual !== undefined && raw.intent !== "perceptual")
      || (label.dataset.noDevice !== undefined && !!d);
    label.classList.toggle("hidden", hidden);
  }
  const hide = (name, show) => form.elements[name].closest("label").classList.toggle("hidden", !show);
  hide("angle", raw.method === "screen" && raw.color !== "cmyk");
  // A group with nothing to set (Colour, with a device) is not shown.
  for (const fs of form.querySelectorAll("fieldset")) {
    const labels = [...fs.querySelectorAll("label")];
    fs.classList.toggle("hidden", labels.length > 0 && labels.every((l) => l.classList.contains("hidden")));
  }
  // A device takes methods diffuse, dbs and ordered; the others are greyed out.
  const allowed = state.listings?.device_methods || [];
  for (const o of form.method.options) o.disabled = !!d && !allowed.includes(o.value);
  if (d && !allowed.includes(form.method.value)) form.method.value = "diffuse";
  // Its size is the fit unless one is given; the buffers it takes are offered.
  form.fit.placeholder = d ? `${d.width}x${d.height} (panel)` : "800x480";
  const info = $("device-info");
  info.classList.toggle("hidden", !d);
  if (d) {
    const nominal = form["ink-colours"].value === "nominal";
    info.replaceChildren();
    info.append(`${d.description}. ${d.ppi} ppi, seen from ${d.viewing_distance_cm} cm; inks (${d.colours}): `);
    for (const ink of d.inks) {
      const sw = document.createElement("span");
      sw.className = "ink";
      sw.style.background = nominal ? ink.nominal : ink.shown;
      sw.title = `${ink.name}: code ${ink.code}, shown ${ink.shown}, nominal ${ink.nominal}`;
      info.append(sw);
    }
  }
  for (const b of $("formats").children) b.classList.toggle("hidden", !!d && !DEVICE_FORMATS.includes(b.dataset.format));
  $("panel-formats").classList.toggle("hidden", !d);
  for (const b of $("panel-formats").querySelectorAll("button")) b.classList.toggle("hidden", !d || !d.encodings.includes(b.dataset.format));
  $("figures-title").textContent = d ? `Compare, as seen on ${d.name}` : "Compare";
}
// The formats that hold a device's inks as colours (the bilevel printer languages do not).
const DEVICE_FORMATS = ["png", "ppm", "tiff", "bmp", "pdf", "ps"];
const PANEL_LABELS = { raw: "RAW", h: "C HEADER (.h)", planes: "PLANES", nibbles: "NIBBLES" };
const PANEL_TITLES = {
  raw: "each pixel's ink code packed MSB first, rows padded to a byte, no header",
  h: "the raw bytes as a C array with width, height and bits defines",
  planes: "black plane, then colour plane: one bit a pixel",
  nibbles: "16 greys, two pixels a byte, even pixel in the low nibble (epdiy)",
};

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
    // A device's measure (S-CIELAB, seconds on a panel-sized picture) runs in a worker of
    // its own, so that it never holds up the next render.
    compare: o.device || o.color === "cmyk" ? null : { dpi: Number(o.dpi) || 300, distance: 12 },
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

// ---- the panel's measure -------------------------------------------------------------
// `compare --device` for the current render, in a second worker started on first use with
// its own copy of the file: one measure at a time, the latest render's after the one running.
const measure = { worker: null, busy: false, wanted: null, loadSent: 0 };
function measureDevice(id, options) {
  measure.wanted = { id, options };
  if (measure.busy) return;
  const job = measure.wanted;
  measure.wanted = null;
  if (!measure.worker) {
    measure.worker = new Worker(new URL("./worker.js", import.meta.url), { type: "module" });
    measure.worker.onmessage = (ev) => {
      measure.busy = false;
      const m = ev.data;
      if (m.type === "error") showCompare({ type: "compared", id: m.id, device: null, error: m.message, ms: 0 });
      else showCompare(m);
      if (measure.wanted) measureDevice(measure.wanted.id, measure.wanted.options);
    };
  }
  measure.busy = true;
  const msg = { type: "measure", id: job.id, loadId: state.loadId, options: job.options };
  if (measure.loadSent !== state.loadId) {
    msg.bytes = state.bytes.slice(0);
    msg.maxPixels = MAX_PIXELS;
    measure.loadSent = state.loadId;
  }
  measure.worker.postMessage(msg, msg.bytes ? [msg.bytes] : []);
}

function showCompare(m) {
  // A measure of an earlier render is not shown over the current one.
  if (state.current && m.id !== state.current.id) return;
  if (!m.measuring) state.lastCompare = m;
  const body = $("quality").tBodies[0];
  body.replaceChildren();
  const row = (k, v) => { const tr = body.insertRow(); tr.insertCell().textContent = k; tr.insertCell().textContent = v; };
  if (m.measuring) {
    row("CIEDE2000", "measuring…");
  } else if (m.device) {
    const f = m.device, n = (x, d = 2) => Number(x).toFixed(d);
    row("CIEDE2000", `${n(f.de2000, 3)} (S-CIELAB mean, viewer adapted to the panel)`);
    row("ΔE*ab", n(f.de76, 3));
    row("lightness", `${n(f.lightness_ratio, 3)} (mean L*, shown / original)`);
    row("pixels a degree", n(f.pixels_per_degree, 1));
    row("measured in", `${m.ms.toFixed(0)} ms (halftone made again in a second worker)`);
  } else if (m.figures) {
    const f = m.figures, n = (x, d = 2) => (x === null ? "∞" : Number(x).toFixed(d));
    row("HVS PSNR", `${n(f.hvs_psnr_db)} dB`);
    row("tone bias", n(f.tone_bias, 4));
    row("L* RMS", n(f.lstar_rms));
    row("plain PSNR", `${n(f.plain_psnr_db)} dB`);
    row("measured in", `${m.ms.toFixed(0)} ms`);
  } else row("compare", m.error);
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
    fill($("intent"), l.intents, "perceptual");
    fill($("ink-colours"), l.ink_colours, "measured");
    for (const d of l.devices) {
      const o = document.createElement("option");
      o.value = d.name;
      o.textContent = `${d.name} (${d.width}×${d.height}, ${d.inks.length} inks)`;
      o.title = d.description;
      $("device").append(o);
    }
    for (const f of l.panel_formats) {
      const b = document.createElement("button");
      b.type = "button";
      b.textContent = PANEL_LABELS[f] || f.toUpperCase();
      b.title = PANEL_TITLES[f] || "";
      b.dataset.format = f;
      b.onclick = () => download(f);
      $("panel-formats").append(b);
    }
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
    state.bytes = state.pendingBytes;
    state.loadId = (state.loadId || 0) + 1;
    state.loads = (state.loads || 0) + 1;
    state.name = m.name;
    draw($("original"), m.width, m.height, m.rgba);
    status(`${m.name}: ${m.width}×${m.height}, decoded in ${m.ms.toFixed(0)} ms`);
    render();
  } else if (m.type === "rendered") {
    draw($("halftone"), m.width, m.height, m.rgba);
    if (state.firstRender === null) state.firstRender = performance.now() - state.loadStart;
    state.last = { id: m.id, convertMs: m.convertMs, totalMs: m.totalMs, width: m.width, height: m.height };
    const what = state.current?.options.device ? `${m.levels} inks` : `${m.levels} levels × ${m.planes} plane${m.planes > 1 ? "s" : ""}`;
    $("timing").textContent = `${m.width}×${m.height}, ${what}: halftoned in ${m.convertMs.toFixed(1)} ms (${m.totalMs.toFixed(1)} ms with display)`;
    status(`${state.name}: ready`);
    if (state.current?.id === m.id && state.current.options.device) {
      showCompare({ type: "compared", id: m.id, measuring: true });
      measureDevice(m.id, state.current.options);
    }
    finish();
  } else if (m.type === "compared") {
    showCompare(m);
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
  // A copy is kept for the panel's measure, whose worker decodes the file on first use.
  state.pendingBytes = bytes.slice(0);
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
