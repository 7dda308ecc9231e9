// a5mi view: the live page (docs/VIEW.md). Plain JS, no library; every request carries the token.
"use strict";
const TOKEN = new URLSearchParams(location.search).get("token") || "";
const api = (path, extra) => path + "?token=" + encodeURIComponent(TOKEN) + (extra || "");
const $ = (id) => document.getElementById(id);
let state = {};
let shownFrame = 0;
let shownCompared = null;
let lastTrace = null;
let shownRegion = null;
const values = { render: null, reference: null };  // pixel values (look.js)

function el(tag, attrs, ...kids) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === "text") e.textContent = v; else e.setAttribute(k, v);
  }
  for (const k of kids) e.append(k);
  return e;
}
const v3 = (v, d) => "(" + v.map((x) => (x === null ? "nan" : Number(x).toPrecision(d || 6).replace(/\.?0+$/, ""))).join(", ") + ")";

// ---------------------------------------------------------------- controls
function buildControls(controls) {
  const form = $("controls");
  if (form.childElementCount) return;
  for (const c of controls) {
    let input;
    if (c.kind === "bool") input = el("input", { type: "checkbox" });
    else if (c.kind === "int") input = el("input", { type: "number", min: c.min, max: c.max, step: 1 });
    else { input = el("select"); for (const ch of c.choices) input.append(el("option", { value: ch, text: ch })); }
    input.name = c.name;
    input.addEventListener("change", sendControls);
    form.append(el("label", {}, input, " " + c.label));
  }
}
function setControls(controls) {
  for (const c of controls || []) {
    const input = $("controls").elements[c.name];
    if (!input || input === document.activeElement) continue;
    if (c.kind === "bool") input.checked = c.value; else input.value = c.value;
  }
}
async function sendControls() {
  const values = {};
  for (const input of $("controls").elements) {
    if (input.type === "checkbox") values[input.name] = input.checked;
    else if (input.type === "number") values[input.name] = Number(input.value);
    else values[input.name] = input.value;
  }
  const r = await fetch(api("/api/render"), { method: "POST", headers: { "Content-Type": "application/json" },
                                              body: JSON.stringify(values) });
  const doc = await r.json();
  $("control-error").hidden = r.ok;
  $("control-error").textContent = r.ok ? "" : doc.error;
}

// ---------------------------------------------------------------- state
function show(s) {
  state = s;
  $("scene").textContent = s.scene || "";
  $("status").textContent = s.preview ? "preview in " + s.seconds.total.toFixed(3) + " s; rendering the full image..."
    : s.composite ? "the region at full quality in " + s.seconds.total.toFixed(3) + " s; rendering the whole image..."
    : s.comparing ? "rendered in " + s.seconds.total.toFixed(3) + " s; comparing..."
    : s.busy ? "rendering..." : (s.seconds ? "rendered in " + s.seconds.total.toFixed(3) + " s" : "");
  if (!s.busy) $("progress").value = 1;
  $("error").hidden = !s.error;
  $("error").textContent = s.error || "";
  if (s.controls) { buildControls(s.controls); setControls(s.controls); }
  $("region-note").hidden = !s.region_note;
  $("region-note").textContent = s.region_note || "";
  $("region-clear").style.visibility = s.region ? "visible" : "hidden";  // its room stays: the images do not move
  $("region-info").textContent = s.region ? "x " + s.region[0] + ".." + (s.region[1] - 1) + ", y " + s.region[2] + ".."
    + (s.region[3] - 1) : "";
  if (JSON.stringify(s.region || null) !== JSON.stringify(shownRegion)) { shownRegion = s.region || null; drawMarks(null); }
  $("warnings").textContent = (s.warnings || []).join("\n");
  const scale = s.size ? Math.max(1, Math.floor(384 / Math.max(s.size[0], s.size[1]))) : 1;
  if (s.frame && s.frame !== shownFrame) {  // a new image: a preview, or the full render (compared or not yet)
    shownFrame = s.frame;
    const img = $("render");
    sizeView("render", s.size, scale);
    img.dataset.pending = s.frame;
    img.dataset.pendingKind = s.preview ? "preview" : s.composite ? "region" : "final";
    img.dataset.pendingComposite = s.composite ? JSON.stringify(s.composite) : "";
    img.dataset.pendingChanges = s.changes || 0;
    img.src = api("/api/image/render.png", "&v=" + s.frame);
    loadValues("render", s.frame, s.size);
    $("render-info").textContent = s.size[0] + "x" + s.size[1];
  }
  if ((s.compared ?? null) !== shownCompared) {  // a new comparison: the frame it belongs to
    shownCompared = s.compared ?? null;
    for (const name of ["reference", "diff"]) {
      const img = $(name);
      sizeView(name, s.size, scale);
      if ((name === "reference" && s.has_reference) || (name === "diff" && s.has_diff)) {
        img.dataset.pending = s.compared;
        img.src = api("/api/image/" + name + ".png", "&v=" + s.compared);
      }
    }
    if (s.has_reference) loadValues("reference", s.compared, null); else values.reference = null;
    $("reference-panel").hidden = !s.has_reference;
    $("diff-panel").hidden = !s.has_diff;
    showMetrics(s);
  }
  // the comparison shown is the last full render's while a preview, a composite or a render not compared yet is shown
  for (const id of ["diff-panel", "compare"]) $(id).classList.toggle("stale", !!(s.preview || s.comparing || s.composite));
  $("exposure-note").textContent = s.reference_float ? "(the reference is an .exr: linear floats)" : "";
  showDiagnosis(s.diagnosis, s.frame);
}
function showMetrics(s) {
  const m = s.metrics;
  $("compare").hidden = !(m || s.reference_error);
  $("reference-name").textContent = (s.reference_name || "").split("/").pop();
  $("reference-name").title = s.reference_name || "";
  $("reference-error").hidden = !s.reference_error;
  $("reference-error").textContent = s.reference_error || "";
  const body = $("metrics").tBodies[0];
  body.replaceChildren();
  $("verdict").textContent = m ? m.verdict : "";
  $("verdict").className = m ? m.verdict : "";
  if (!m) return;
  const rows = [["PSNR", m.psnr === null ? "inf dB (identical)" : m.psnr.toFixed(2) + " dB"],
                ["mean error", m.mean_error.toFixed(3) + "/255"],
                ["pixels > " + m.threshold + "/255", (100 * m.share_over).toFixed(3) + "%"],
                ["max error", m.max_error + "/255"],
                ["beyond " + m.noise_floor + "/255 (verdict)", (100 * m.beyond_noise).toFixed(3) + "%"]];
  if (m.bbox) rows.push(["over the threshold in", "x " + m.bbox[0] + ".." + m.bbox[2] + ", y " + m.bbox[1] + ".." + m.bbox[3]]);
  for (const [k, v] of rows) body.append(el("tr", {}, el("td", { text: k }), el("td", { text: v })));
  const stops = m.stops.map((c, i) => `rgb(${c.join(",")}) ${(100 * i) / (m.stops.length - 1)}%`);
  $("colorbar").style.background = "linear-gradient(to right, " + stops.join(", ") + ")";
  $("bar-mid").textContent = m.scale / 2;
  $("bar-max").textContent = m.scale + "/255";
}
for (const name of ["render", "reference", "diff"]) {
  $(name).addEventListener("load", () => {
    const img = $(name);
    img.dataset.frame = img.dataset.pending;
    img.dataset.kind = img.dataset.pendingKind;
    img.dataset.changes = img.dataset.pendingChanges;
    img.dataset.composite = img.dataset.pendingComposite || "";
    img.dataset.loadedAt = Date.now();
    if (name === "render") {
      // a preview is labelled as one while it is the image shown; the compare panels are the last full render's
      const preview = img.dataset.kind === "preview";
      $("preview-badge").hidden = !preview;
      // a composite: the marked region at full quality pasted on the image shown before (or on the preview)
      const c = img.dataset.composite ? JSON.parse(img.dataset.composite) : null;
      $("region-badge").hidden = !c;
      if (c) $("region-badge").textContent = "REGION x " + c.region[0] + ".." + (c.region[1] - 1) + ", y " + c.region[2]
        + ".." + (c.region[3] - 1) + " at full quality, pasted on " + ({ previous: "the previous image",
          preview: "the preview", blank: "a blank image (the size changed)" })[c.base]
        + (c.base === "preview" ? "" : ": the whole render follows");
    }
    applyView(); drawShown(); drawMarks(null);
  });
}

// ---------------------------------------------------------------- events
setupLook();
const events = new EventSource(api("/api/events"));
events.addEventListener("state", (e) => show(JSON.parse(e.data)));
events.addEventListener("progress", (e) => {
  const p = JSON.parse(e.data);
  $("progress").value = p.total ? p.done / p.total : 0;
  let text = p.stage + (p.total > 1 ? " " + Math.round((100 * p.done) / p.total) + "%" : "");
  // the work estimate (docs/USAGE.md "Work estimate and progress"): rays so far (at most) and the time left
  if (p.rays !== undefined && p.eta !== undefined) {
    const eta = p.eta < 90 ? Math.round(p.eta) + " s" : Math.round(p.eta / 60) + " min";
    text += " (up to " + Number(p.rays).toPrecision(2) + " rays, eta " + eta + ")";
  }
  $("status").textContent = text + "...";
  $("status").title = p.estimate || "";
});
events.addEventListener("error", () => { if (events.readyState !== EventSource.OPEN) $("status").textContent = "reconnecting"; });

// ---------------------------------------------------------------- trace
async function tracePixel(x, y) {
  $("trace").replaceChildren(el("p", { text: "tracing pixel (" + x + ", " + y + ")..." }));
  const r = await fetch(api("/api/trace", "&x=" + x + "&y=" + y));
  const doc = await r.json();
  if (!r.ok) { $("trace").replaceChildren(el("p", { class: "error", text: doc.error })); return; }
  lastTrace = doc;
  showTrace(doc);
  drawMarks(null);
}
function nodeView(n, i) {
  const head = "#" + n.index + " " + n.kind + " ray, weight " + v3(n.weight, 4);
  const lines = [];
  if (n.hit > 0.5) {
    const obj = n.object ? n.object.kind + " at line " + n.object.line : "an object";
    lines.push("hit " + obj + " at t " + Number(n.t).toPrecision(6) + ", p " + v3(n.p, 4) + (n.inside ? ", inside" : ""));
    lines.push("ambient term " + v3(n.ambient_term, 4));
    for (const l of n.lights) {
      const how = !l.tested ? "" : l.visible ? " lit" : " blocked" + (l.occluder ? " by " + l.occluder.kind + " at line " + l.occluder.line : "");
      lines.push("light " + l.index + " (" + l.name + "):" + how + " N·L " + Number(l.n_dot_l).toPrecision(4) + " term " + v3(l.term, 4) + (l.visible ? "" : " (not added)"));
    }
    lines.push("local " + v3(n.local, 4));
  } else {
    lines.push("miss: background " + v3(n.background, 4));
  }
  lines.push("contribution = weight ⊙ local = " + v3(n.contribution, 6));
  const div = el("div", { class: "node", "data-index": i, style: "margin-left:" + 1.2 * n.depth + "em" },
                 el("div", { text: head }), el("div", { class: "terms", text: lines.join("\n") }));
  div.style.whiteSpace = "pre-wrap";
  div.addEventListener("mouseenter", () => { div.classList.add("hot"); drawMarks(i); });
  div.addEventListener("mouseleave", () => { div.classList.remove("hot"); drawMarks(null); });
  return div;
}
function showTrace(doc) {
  const out = [];
  const k = doc.shown, sample = doc.samples[k];
  out.push(el("p", { text: "pixel (" + doc.clicked[0] + ", " + doc.clicked[1] + ") of the image; a5mi trace -pixel "
    + doc.pixel[0] + " " + doc.pixel[1] + " (grid " + doc.grid[0] + "x" + doc.grid[1] + ")"
    + (doc.samples.length > 1 ? "; tree of sample " + k + " of " + doc.samples.length : "") }));
  sample.nodes.forEach((n, i) => out.push(nodeView(n, i)));
  const sumByte = sample.sum_byte;
  const pix = doc.image_byte;
  const single = doc.samples.length === 1;
  const agree = single ? sumByte.join() === pix.join() : doc.value_byte.join() === pix.join();
  out.push(el("p", { class: "sum", id: "trace-sum", "data-byte": sumByte.join(","), "data-value-byte": doc.value_byte.join(","),
                     "data-pixel": pix.join(","),
                     text: "Σ contributions = " + v3(sample.sum, 9) + " → 8-bit (" + sumByte.join(", ") + ")"
                       + (single ? "" : "; pixel value from all samples (" + doc.value_byte.join(", ") + ")")
                       + "; image pixel (" + pix.join(", ") + ")" }));
  out.push(el("p", { class: agree ? "ok" : "bad", id: "trace-check", text: agree ? "the tree sums to the pixel" : "the tree does NOT sum to the pixel" }));
  if (doc.diff) {
    const d = doc.diff;
    const list = el("ul", { id: "diff-explain" });
    for (const t of d.terms) list.append(el("li", { text: (t.sign > 0 ? "the reference adds " : "the reference lacks ") + t.label + ": " + v3(t.value, 4) + " (leaves " + (255 * t.residual).toFixed(1) + "/255)" }));
    const say = d.off_by <= d.noise ? "within " + d.noise + "/255: nothing differs" :
      d.terms.length ? "look at:" : "no single term of the tree accounts for the difference";
    out.push(el("div", {}, el("h2", { text: "trace --diff: reference pixel (" + d.other_byte.join(", ") + "), off by " + d.off_by + "/255" }),
                el("p", { text: say }), list));
  }
  out.push(el("details", {}, el("summary", { text: "a5mi trace text" }), el("pre", { text: doc.text })));
  $("trace").replaceChildren(...out);
}
