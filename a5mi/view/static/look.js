// a5mi view: looking closely (docs/VIEW.md "Look closely"): zoom and pan of the three images locked together,
// the values under the cursor, exposure, the A/B flip, the clicked pixel's mark, the marked region (shift+drag:
// rendered first at full quality on each save, docs/VIEW.md "Full quality first") and the diagnose panel.
// Loaded before view.js, whose globals ($, api, state, values, lastTrace, tracePixel, el) it uses at call time.
"use strict";
const ZOOMS = [1, 2, 4, 8, 16];
const look = { z: 1, tx: 0, ty: 0, base: 1, hover: null, flip: false, ev: 0, drag: null, sel: null };

// ------------------------------------------------------------------ geometry
// Screen (CSS px inside a view) = (tx, ty) + z * base * image pixel: base is the page's fit scale (image px to CSS
// px at 1x), z the zoom (nearest neighbour: image-rendering: pixelated).
function sizeView(name, size, scale) {
  const v = $("view-" + name), img = $(name);
  look.base = scale;
  img.style.width = size[0] * scale + "px"; img.style.height = size[1] * scale + "px";
  v.style.width = size[0] * scale + "px"; v.style.height = size[1] * scale + "px";
  const c = v.querySelector("canvas.shown");
  if (c) { c.style.width = img.style.width; c.style.height = img.style.height; }
  clampPan(); applyView();
}
function viewSize() { const v = $("view-render"); return [v.clientWidth, v.clientHeight]; }
function clampPan() {
  const [w, h] = viewSize();
  look.tx = Math.round(Math.min(0, Math.max(w - w * look.z, look.tx)));
  look.ty = Math.round(Math.min(0, Math.max(h - h * look.z, look.ty)));
}
function applyView() {
  for (const name of ["render", "reference", "diff"]) {
    const st = $("view-" + name).querySelector(".stack");
    st.style.transform = "translate(" + look.tx + "px, " + look.ty + "px) scale(" + look.z + ")";
    const m = $("view-" + name).querySelector("canvas.mark");
    const v = $("view-" + name);
    if (m.width !== v.clientWidth || m.height !== v.clientHeight) { m.width = v.clientWidth; m.height = v.clientHeight; }
  }
  const vr = $("view-render");
  vr.dataset.zoom = look.z; vr.dataset.tx = look.tx; vr.dataset.ty = look.ty; vr.dataset.base = look.base;
}
function setZoom(z, cx, cy) {  // about the view point (cx, cy): the image point there stays
  z = Math.min(16, Math.max(1, z));
  look.tx = cx - ((cx - look.tx) * z) / look.z;
  look.ty = cy - ((cy - look.ty) * z) / look.z;
  look.z = z;
  $("zoom").value = String(z);
  clampPan(); applyView(); drawMarks(null);
}
function imagePixel(vx, vy) {  // the image pixel under the view point, or null outside the image
  const img = $("render");
  if (!img.naturalWidth) return null;
  const k = look.z * look.base * (img.naturalWidth / (state.size ? state.size[0] : img.naturalWidth));
  const x = Math.floor((vx - look.tx) / k), y = Math.floor((vy - look.ty) / k);
  return x >= 0 && y >= 0 && x < img.naturalWidth && y < img.naturalHeight ? [x, y] : null;
}
function clampedPixel(vx, vy) {  // the image pixel under the view point, clamped to the image
  const img = $("render"), w = img.naturalWidth, h = img.naturalHeight;
  const k = look.z * look.base * (w / (state.size ? state.size[0] : w));
  return [Math.min(w - 1, Math.max(0, Math.floor((vx - look.tx) / k))),
          Math.min(h - 1, Math.max(0, Math.floor((vy - look.ty) / k)))];
}

// ------------------------------------------------------------------ the marked region
// [X0, X1, Y0, Y1]: image pixels X0 <= x < X1, Y0 <= y < Y1, row 0 the top (a5 -crop's order): the two pixels under
// the ends of a shift+drag and every pixel between them.
function selRegion(s) {
  return [Math.min(s.a[0], s.b[0]), Math.max(s.a[0], s.b[0]) + 1, Math.min(s.a[1], s.b[1]), Math.max(s.a[1], s.b[1]) + 1];
}
async function postRegion(region) {
  const r = await fetch(api("/api/region"), { method: "POST", headers: { "Content-Type": "application/json" },
                                              body: JSON.stringify({ region: region }) });
  const doc = await r.json();
  $("region-error").hidden = r.ok;
  $("region-error").textContent = r.ok ? "" : doc.error;
}
function drawRegion(g, k) {  // the marked region (or the one being dragged): dashed yellow over black
  const r = look.sel && look.sel.moved ? selRegion(look.sel) : state.region;
  if (!r) return;
  const x = look.tx + r[0] * k, y = look.ty + r[2] * k, w = (r[1] - r[0]) * k, h = (r[3] - r[2]) * k;
  g.save();
  g.strokeStyle = "#000"; g.lineWidth = 3; g.strokeRect(x - 0.5, y - 0.5, w + 1, h + 1);
  g.strokeStyle = "#fd6"; g.lineWidth = 1; g.setLineDash([4, 3]); g.strokeRect(x - 0.5, y - 0.5, w + 1, h + 1);
  g.restore();
}

// ------------------------------------------------------------------ values
async function loadValues(name, version, size) {
  const r = await fetch(api("/api/values/" + name + ".bin", "&v=" + version));
  if (!r.ok) return;
  const buf = await r.arrayBuffer();
  const dims = size || state.size;
  const n = dims[0] * dims[1] * 3;
  if (buf.byteLength !== 5 * n) return;  // a newer image replaced it meanwhile: its own fetch follows
  values[name] = { w: dims[0], h: dims[1], version: version, lin: new Float32Array(buf, 0, n),
                   byte: new Uint8Array(buf, 4 * n, n) };
  drawShown(); showValues();
}
// SPEC B.1's quantisation of c·m (float32 products, truncation, clamp; what int32 cannot hold is 0)
function quantize(c, m) {
  const s = Math.fround(Math.fround(c * m) * 255);
  if (!(s < 2147483648 && s >= -2147483648)) return 0;
  return Math.min(255, Math.max(0, Math.trunc(s)));
}
function pixelOf(name, x, y) {
  const v = values[name];
  if (!v || x >= v.w || y >= v.h) return null;
  const i = 3 * (y * v.w + x);
  return { lin: [v.lin[i], v.lin[i + 1], v.lin[i + 2]], byte: [v.byte[i], v.byte[i + 1], v.byte[i + 2]] };
}
function showValues() {
  const p = look.hover;
  const table = $("values");
  table.style.visibility = p ? "visible" : "hidden";  // its room stays: the images do not move under the cursor
  if (!p) return;
  $("values-at").textContent = "pixel (" + p[0] + ", " + p[1] + ")";
  table.dataset.x = p[0]; table.dataset.y = p[1];
  const r = pixelOf("render", p[0], p[1]), f = pixelOf("reference", p[0], p[1]);
  const d = r && f ? { lin: r.lin.map((c, i) => c - f.lin[i]), byte: r.byte.map((c, i) => c - f.byte[i]) } : null;
  for (const [id, v] of [["render", r], ["reference", f], ["diff", d]]) {
    const row = $("values-" + id);
    row.style.visibility = v ? "visible" : "hidden";  // hidden, not removed: the table keeps its height
    if (!v) continue;
    row.dataset.linear = v.lin.join(","); row.dataset.byte = v.byte.join(",");
    row.cells[1].textContent = "(" + v.lin.map((c) => c.toFixed(5)).join(", ") + ")";
    row.cells[2].textContent = "(" + v.byte.join(", ") + ")"
      + (id === "diff" ? " max |" + Math.max(...v.byte.map(Math.abs)) + "|/255" : "");
  }
}

// ------------------------------------------------------------------ exposure and the A/B flip
// A canvas over the image shows it when the exposure is not 0 (quantize(c·2^EV)), when it is an .exr reference, or
// in the render's place the reference (the flip); at 0 EV the canvas holds the 8-bit levels (the render's: the PNG's
// pixels; an .exr's: SPEC B.1's quantize(c)).
function paint(canvas, v) {
  if (!v) return false;
  const m = Math.fround(2 ** look.ev);
  canvas.width = v.w; canvas.height = v.h;
  const g = canvas.getContext("2d"), out = g.createImageData(v.w, v.h);
  for (let i = 0, j = 0; i < v.lin.length; i += 3, j += 4) {
    for (let k = 0; k < 3; k++) out.data[j + k] = look.ev === 0 ? v.byte[i + k] : quantize(v.lin[i + k], m);
    out.data[j + 3] = 255;
  }
  g.putImageData(out, 0, 0);
  return true;
}
function drawShown() {
  const flip = look.flip && values.reference && values.render && values.reference.w === values.render.w
    && values.reference.h === values.render.h;
  const rc = $("render-canvas"), fc = $("reference-canvas");
  rc.hidden = !((look.ev !== 0 || flip) && paint(rc, flip ? values.reference : values.render));
  rc.dataset.shows = rc.hidden ? "" : flip ? "reference" : "render";
  fc.hidden = !((look.ev !== 0 || state.reference_float) && paint(fc, values.reference));  // an .exr: its floats
  $("render-title").textContent = flip ? "reference (A/B flip: F)" : "render";
  $("flip").classList.toggle("on", !!flip);
}

// ------------------------------------------------------------------ marks
// The clicked pixel: a box around it (the pixel's size at the zoom, at least 7 CSS px) and four crosshair arms,
// each drawn black under white so it shows on any colour; on all three images. Hovering a tree node: its hit point.
function drawMarks(hot) {
  for (const name of ["render", "reference", "diff"]) {
    const c = $("view-" + name).querySelector("canvas.mark"), g = c.getContext("2d");
    g.clearRect(0, 0, c.width, c.height);
    const img = $("render");
    if (!img.naturalWidth) continue;
    const k = look.z * look.base * (img.naturalWidth / state.size[0]);
    drawRegion(g, k);
    if (!lastTrace) continue;
    const [px, py] = lastTrace.clicked;
    const cx = look.tx + (px + 0.5) * k, cy = look.ty + (py + 0.5) * k, r = Math.max(k / 2 + 1.5, 3.5);
    for (const [colour, width] of [["#000", 3], ["#fff", 1]]) {
      g.strokeStyle = colour; g.lineWidth = width;
      g.strokeRect(cx - r, cy - r, 2 * r, 2 * r);
      g.beginPath();
      for (const [dx, dy] of [[1, 0], [-1, 0], [0, 1], [0, -1]]) {
        g.moveTo(cx + dx * (r + 3), cy + dy * (r + 3)); g.lineTo(cx + dx * (r + 14), cy + dy * (r + 14));
      }
      g.stroke();
    }
    if (hot === null || name !== "render") continue;
    const m = lastTrace.marks[hot];
    if (!m) continue;
    const mx = look.tx + (m[0] + 0.5) * k, my = look.ty + (m[1] + 0.5) * k;
    g.strokeStyle = "#fd6"; g.lineWidth = 2;
    g.beginPath(); g.arc(mx, my, 7, 0, 2 * Math.PI); g.stroke();
    g.beginPath(); g.moveTo(mx - 11, my); g.lineTo(mx + 11, my); g.moveTo(mx, my - 11); g.lineTo(mx, my + 11); g.stroke();
  }
}

// ------------------------------------------------------------------ diagnose
const pct = (x) => (x === null || x === undefined ? "-" : (100 * x).toFixed(1) + "%");
const db = (x) => (x === null || x === undefined ? "inf" : x.toFixed(1));
// a closest cause of an unexplained image, as `a5mi diagnose` prints it: ranked by the likelihood with each
// mistake's own jitter noise (docs/MISTAKES.md "Closest causes"), whose explained share may be negative
function closestText(c) {
  return c.mistakes.join(" + ") + " (explains " + pct(c.explained)
    + (c.likelihood === null || c.likelihood === undefined ? ""
      : ", likelihood ratio " + (c.likelihood >= 0 ? "+" : "") + c.likelihood.toFixed(3) + " nats per value") + ")";
}

function showDiagnosis(d, frame) {
  const out = $("diagnosis");
  out.dataset.status = d ? d.status : "";
  if (!d) { out.replaceChildren(); return; }
  if (d.status === "queued" || d.status === "running") {
    out.replaceChildren(el("p", { text: "diagnosing the " + d.image + " (renders the mutants)..." })); return;
  }
  if (d.status === "error") { out.replaceChildren(el("p", { class: "error", text: d.error })); return; }
  const kids = [el("p", { text: "the " + d.image + " of frame " + d.frame + " against a5mi's render with " + d.flags
    + (d.mistakes.length ? " (the render was made with -mistake " + d.mistakes.join(",") + ")" : "")
    + ": PSNR " + db(d.psnr) + " dB" + (d.frame !== frame ? " [an older frame: diagnose again]" : "") })];
  const best = d.causes[0];
  const verdict = d.verdict === "match" ? "match: within the noise, no mistake found"
    : d.verdict === "unexplained" ? "unexplained: no catalogued mistake explains the difference; remaining error PSNR "
      + db(d.remaining > 0 ? -10 * Math.log10(d.remaining) : null) + " dB"
      + (best ? " (closest: " + d.causes.map(closestText).join("; ") + ")" : "")
    : "diagnosis: " + best.mistakes.join(" + ");
  kids.push(el("p", { id: "diagnosis-verdict", class: d.verdict, "data-verdict": d.verdict, text: verdict }));
  if (d.verdict === "diagnosis") {
    const list = el("ol", { id: "diagnosis-causes" });
    for (const c of d.causes) {
      const lines = [c.mistakes.join(" + ") + ": explains " + pct(c.explained) + " of the difference"
        + (c.scale === "blocks" ? " (in 4x4 block means)" : "")
        + (c.partner ? "; the paired score prefers it to " + c.mistakes.find((m) => m !== c.partner) + " alone, z = "
          + c.partner_z.toFixed(1) : "")];
      for (const m of c.catalogue) lines.push(m.name + " (SPEC " + m.section + "): " + m.change, "symptom: " + m.symptom);
      const e = c.evidence;
      if (e && e.box) lines.push("where: x " + e.box[0] + ".." + (e.box[2] - 1) + ", y " + e.box[1] + ".." + (e.box[3] - 1)
        + " (" + e.region + ", row 0 = top); " + pct(e.differing) + " of pixels differ, " + pct(e.fixed)
        + " of them reproduced; PSNR " + db(e.psnr_before) + " -> " + db(e.psnr_after) + " dB");
      list.append(el("li", { class: "cause", "data-mistakes": c.mistakes.join(","), text: lines.join("\n") }));
    }
    kids.push(list);
  }
  out.replaceChildren(...kids);
}
async function requestDiagnosis() {
  const r = await fetch(api("/api/diagnose"), { method: "POST", headers: { "Content-Type": "application/json" },
                                                body: JSON.stringify({ image: $("diagnose-image").value }) });
  if (!r.ok) $("diagnosis").replaceChildren(el("p", { class: "error", text: (await r.json()).error }));
}

// ------------------------------------------------------------------ input
function setupLook() {
  $("zoom").addEventListener("change", () => {
    const [w, h] = viewSize();
    const img = $("render");
    if (lastTrace && img.naturalWidth) {  // about the clicked pixel, else the centre
      const k = look.z * look.base * (img.naturalWidth / state.size[0]);
      setZoom(Number($("zoom").value), look.tx + (lastTrace.clicked[0] + 0.5) * k, look.ty + (lastTrace.clicked[1] + 0.5) * k);
    } else setZoom(Number($("zoom").value), w / 2, h / 2);
  });
  $("exposure").addEventListener("input", () => { look.ev = Number($("exposure").value) || 0; drawShown(); });
  $("flip").addEventListener("click", () => { look.flip = !look.flip; drawShown(); });
  document.addEventListener("keydown", (e) => {
    if (["INPUT", "SELECT"].includes(document.activeElement.tagName)) return;
    if (e.key === "f" || e.key === "F") { look.flip = !look.flip; drawShown(); }
    if (e.key === "Escape" && state.region) postRegion(null);
  });
  $("region-clear").addEventListener("click", () => postRegion(null));
  $("diagnose").addEventListener("click", requestDiagnosis);
  for (const name of ["render", "reference", "diff"]) {
    const v = $("view-" + name);
    const at = (e) => { const b = v.getBoundingClientRect(); return [e.clientX - b.left, e.clientY - b.top]; };
    v.addEventListener("wheel", (e) => {
      e.preventDefault();
      const [x, y] = at(e);
      const i = ZOOMS.indexOf(look.z);
      setZoom(ZOOMS[Math.max(0, Math.min(ZOOMS.length - 1, i + (e.deltaY < 0 ? 1 : -1)))], x, y);
    }, { passive: false });
    v.addEventListener("mousedown", (e) => {
      if (e.button !== 0) return;
      e.preventDefault();
      if (e.shiftKey && $("render").naturalWidth) {  // shift+drag: mark a region (not a pan, not a click)
        const p = clampedPixel(...at(e));
        look.sel = { view: v, x: e.clientX, y: e.clientY, a: p, b: p, moved: false };
        return;
      }
      look.drag = { x: e.clientX, y: e.clientY, tx: look.tx, ty: look.ty, moved: false };
    });
    v.addEventListener("mousemove", (e) => {
      const [x, y] = at(e);
      look.hover = imagePixel(x, y);
      showValues();
    });
    v.addEventListener("mouseleave", () => { look.hover = null; showValues(); });
    v.addEventListener("mouseup", (e) => {
      const d = look.drag;
      look.drag = null;
      if (!d || d.moved || e.button !== 0) return;
      const p = imagePixel(...at(e));
      if (p) tracePixel(p[0], p[1]);
    });
  }
  window.addEventListener("mousemove", (e) => {
    const s = look.sel;
    if (s) {
      if (Math.abs(e.clientX - s.x) + Math.abs(e.clientY - s.y) > 3) s.moved = true;
      const b = s.view.getBoundingClientRect();
      s.b = clampedPixel(e.clientX - b.left, e.clientY - b.top);
      drawMarks(null);
      return;
    }
    const d = look.drag;
    if (!d) return;
    if (Math.abs(e.clientX - d.x) + Math.abs(e.clientY - d.y) > 3) d.moved = true;
    if (!d.moved) return;
    look.tx = d.tx + e.clientX - d.x; look.ty = d.ty + e.clientY - d.y;
    clampPan(); applyView(); drawMarks(null);
  });
  window.addEventListener("mouseup", (e) => {  // after the view's own (bubbling)
    look.drag = null;
    const s = look.sel;
    look.sel = null;
    if (!s || !s.moved) return;
    const b = s.view.getBoundingClientRect();
    s.b = clampedPixel(e.clientX - b.left, e.clientY - b.top);
    state.region = selRegion(s);  // shown at once; the server's state confirms it
    drawMarks(null);
    postRegion(state.region);
  });
}
