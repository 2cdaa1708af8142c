// Runs the WebAssembly library off the page's thread: decodes once, halftones on every
// change of the options, measures and encodes on request. The page starts a second one for
// the panel's measure (`measure` messages), which is too slow to wait for between renders.
import init, { Source, listings } from "./pkg/halftone_web.js";

const ready = init(new URL("./pkg/halftone_web_bg.wasm", import.meta.url));
let source = null;
let rendered = null;

function fail(id, e) {
  postMessage({ type: "error", id, message: String(e && e.message ? e.message : e) });
}

self.onmessage = async (ev) => {
  const m = ev.data;
  try {
    await ready;
    if (m.type === "listings") {
      postMessage({ type: "listings", listings: JSON.parse(listings()) });
    } else if (m.type === "load") {
      const t0 = performance.now();
      const s = new Source(new Uint8Array(m.bytes), m.maxPixels);
      if (source) source.free();
      if (rendered) { rendered.free(); rendered = null; }
      source = s;
      const rgba = s.rgba();
      postMessage({ type: "loaded", id: m.id, name: m.name, width: s.width, height: s.height,
        color: s.color, rgba, ms: performance.now() - t0 }, [rgba.buffer]);
    } else if (m.type === "render") {
      if (!source) throw new Error("no image loaded");
      const t0 = performance.now();
      const r = source.convert(JSON.stringify(m.options));
      const t1 = performance.now();
      if (rendered) rendered.free();
      rendered = r;
      let rgba, width = r.width, height = r.height;
      if (m.view === "preview") {
        const size = r.preview_size();
        if (size.length !== 2) throw new Error("no press preview: it is made for CMYK plates");
        [width, height] = size;
        rgba = r.preview_rgba();
      } else {
        rgba = r.rgba(m.view || "composite");
      }
      const t2 = performance.now();
      postMessage({ type: "rendered", id: m.id, width, height, levels: r.levels, planes: r.planes,
        rgba, convertMs: t1 - t0, totalMs: t2 - t0 }, [rgba.buffer]);
      if (m.compare) {
        const t3 = performance.now();
        let figures = null, error = null;
        try { figures = JSON.parse(r.compare(source, m.compare.dpi, m.compare.distance)); }
        catch (e) { error = String(e.message || e); }
        postMessage({ type: "compared", id: m.id, figures, error, ms: performance.now() - t3 });
      }
    } else if (m.type === "measure") {
      // The panel's measure, in the page's second worker: its own copy of the file, decoded
      // when a new one comes, the halftone made again (the same bytes) and measured.
      if (m.bytes) {
        if (source) source.free();
        source = null;
        source = new Source(new Uint8Array(m.bytes), m.maxPixels);
      }
      if (!source) throw new Error("no image loaded");
      const t0 = performance.now();
      const r = source.convert(JSON.stringify(m.options));
      let device = null, error = null;
      try { device = JSON.parse(r.compare_device(source)); }
      catch (e) { error = String(e.message || e); }
      r.free();
      postMessage({ type: "compared", id: m.id, device, error, ms: performance.now() - t0 });
    } else if (m.type === "encode") {
      if (!rendered) throw new Error("nothing rendered yet");
      const files = rendered.encode_files(m.format);
      const out = [];
      for (let i = 0; i < files.length; i++) out.push({ suffix: files.suffix(i), bytes: files.bytes(i) });
      files.free();
      if (m.format === "png" && m.preview) {
        try { out.push({ suffix: "-preview", bytes: rendered.preview_png() }); } catch (_) { /* no preview */ }
      }
      postMessage({ type: "files", id: m.id, format: m.format, files: out }, out.map((f) => f.bytes.buffer));
    }
  } catch (e) {
    fail(m.id, e);
  }
};
