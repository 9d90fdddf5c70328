// The style sheet, the plot containers and the script of report.html (internal).
//
// Why hand-written SVG and vanilla JavaScript, not a plotting library: the report must open
// offline as one file, stay small (a vendored library is 100 kB-1 MB before any data) and be
// byte-identical for the same comparison; the plots it needs (lines, boxes, ellipses, a colour
// map) take a few hundred lines. The script reads the JSON block #wg-data and draws every plot
// from it, so toggling estimators refits the axes to what is shown.
//
// Layout self-check: after drawing, the script writes into <pre id="wg-check"> a JSON object
// with the colour of each estimator's line as drawn, whether they are distinct, the number of
// legend boxes (.legend) and plot areas (.plot-area) and every overlap between the two in page
// coordinates, and the time the last drawing of every plot took. The Chromium test (tests/html_report_test.cc) reads it from --dump-dom.
#ifndef WALKGRAPH_SRC_REPORT_REPORT_SCRIPT_H_
#define WALKGRAPH_SRC_REPORT_REPORT_SCRIPT_H_

namespace walkgraph::report {

inline constexpr const char kReportCss[] = R"CSS(
body{font-family:system-ui,sans-serif;margin:16px;color:#222;max-width:1700px}
h1{font-size:22px;margin:4px 0}h2{font-size:17px;margin:18px 0 6px}
table{border-collapse:collapse;font-size:13px}
td,th{border:1px solid #ddd;padding:2px 7px;text-align:right;white-space:nowrap}
#results thead th{cursor:pointer;background:#f3f3f3;position:sticky;top:0}
#results thead th.asc::after{content:" \25B2"}#results thead th.desc::after{content:" \25BC"}
td.name,#unranked td{text-align:left}td.why{white-space:normal;max-width:700px}
tr.fam th{text-align:left;background:#fafafa;font-weight:600;color:#555}
td.best{font-weight:700;background:#e6f4e6}td.best::after{content:" \2605";color:#2a8a2a}
tr.est{cursor:pointer}tr.est.hl td{background:#fff3c4}tr.off td{color:#aaa}
.sw{display:inline-block;width:12px;height:12px;margin:0 5px -1px 3px;border:1px solid #0003}
.summary{font-size:15px}.hint,.note{font-size:12px;color:#555}
.warn{font-size:13px;color:#8a4b00;margin-top:8px}.warn ul{margin:2px 0 0 0}
#plots{display:grid;grid-template-columns:210px 1fr;gap:12px;align-items:start;margin-top:12px}
#legend{position:sticky;top:4px;font-size:12px;border:1px solid #ccc;padding:6px;background:#fff}
#legend div.it{cursor:pointer;white-space:nowrap;line-height:18px}#legend div.it.off{opacity:.35}
#legend div.fl{font-weight:600;color:#555;margin-top:4px}
#figs{display:flex;flex-wrap:wrap;gap:14px}
.fig{border:1px solid #eee;padding:4px}.fig .cap{font-size:11px;color:#555;max-width:600px}
.key{font-size:11px;color:#333;margin:2px 0 0 8px}.key span{margin-right:12px}
#ape-grid{display:flex;flex-wrap:wrap;gap:4px;max-width:1290px}
svg text{font-size:11px;fill:#222}svg .ttl{font-size:13px;font-weight:600}
svg .grid{stroke:#e4e4e4}
body.hl-on svg [data-id]:not(.hl){opacity:.12}body.hl-on svg .hl{stroke-width:3}
#wg-check{display:none}
)CSS";

inline constexpr const char kReportBody[] = R"HTML(
<noscript><p><b>The plots are drawn by the page's script: enable JavaScript to see
them.</b></p></noscript>
<p class="hint"><label><input type="checkbox" id="logerr"> log error axis</label> (on by
default when the estimators' errors differ by more than a factor of 10)</p>
<div id="plots"><div id="legend" class="legend"></div><div id="figs">
<div class="fig" id="f-traj"><div id="p-traj"></div><div class="legend key" id="k-traj"></div>
<div class="cap">Wheel: zoom at the pointer; drag: pan; double-click: fit.</div></div>
<div class="fig" id="f-time"><div id="p-time"></div><div class="legend key" id="k-time"></div></div>
<div class="fig" id="f-dist"><div id="p-dist"></div></div>
<div class="fig" id="f-cdf"><div id="p-cdf"></div></div>
<div class="fig" id="f-box"><div id="p-box"></div><div class="cap">Box: quartiles and median;
whiskers: 5th and 95th percentiles; dot: RMSE. Sorted by median.</div></div>
<div class="fig" id="f-ell"><div class="key"><label>covariance of
<select id="ell-sel"></select></label></div><div id="p-ell"></div><div class="legend key"
id="k-ell"></div></div>
<div class="fig" id="f-nees"><div id="p-nees"></div><div class="legend key" id="k-nees"></div></div>
<div class="fig" id="f-runs"><div id="p-runs"></div><div class="legend key" id="k-runs"></div></div>
<div class="fig" id="f-ape" style="flex-basis:100%"><div class="ttl"><b>Error along each
trajectory</b> (evo's APE map: the estimate coloured by its horizontal error; truth in grey)</div>
<div class="legend key" id="k-ape"></div><div id="ape-grid"></div></div>
</div></div>
<pre id="wg-check"></pre>
)HTML";

inline constexpr const char kReportJs[] = R"JS(
(function () {
'use strict';
const D = JSON.parse(document.getElementById('wg-data').textContent);
const NS = 'http://www.w3.org/2000/svg';
const E = D.est;
const hidden = new Set();
let pinned = null, zoom = null;
// Ellipses: of the lowest-RMSE estimator with covariances first.
const ellEst = E.filter(e => e.el.length > 0).sort((a, b) => a.rmse - b.rmse || (a.id < b.id ? -1 : 1));
let ellId = ellEst.length ? ellEst[0].id : null;

function el(tag, attrs, parent) {
  const e = document.createElementNS(NS, tag);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  if (parent) parent.appendChild(e);
  return e;
}
function txt(parent, x, y, s, extra) {
  const t = el('text', Object.assign({x: x, y: y}, extra || {}), parent);
  t.textContent = s;
  return t;
}
// "Nice numbers" (Heckbert 1990): a step of 1, 2 or 5 times a power of ten.
function niceStep(span, n) {
  const raw = span / n, p = Math.pow(10, Math.floor(Math.log10(raw))), f = raw / p;
  return (f < 1.5 ? 1 : f < 3 ? 2 : f < 7 ? 5 : 10) * p;
}
function decimals(step) { return Math.max(0, -Math.floor(Math.log10(step) + 1e-9)); }
function visible() { return E.filter(e => !hidden.has(e.id)); }
function pairs(a, n) { const out = []; for (let i = 0; i + n <= a.length; i += n) out.push(a.slice(i, i + n)); return out; }

// One axis: a nice range and ticks (raw: the range as given); log10 when `log` (decades, with
// 2 and 5 between when it spans fewer than three); `step` forces the tick step.
function axis(lo, hi, n, log, raw, step) {
  if (log) {
    lo = Math.max(lo, 1e-6);
    if (!(hi > lo)) hi = lo * 10;
    const a = Math.floor(Math.log10(lo) + 1e-9), b = Math.max(a + 1, Math.ceil(Math.log10(hi) - 1e-9));
    const ticks = [];
    for (let k = a; k <= b; k++) for (const f of (b - a < 3 ? [1, 2, 5] : [1])) if (k < b || f === 1) ticks.push(f * Math.pow(10, k));
    return {lo: Math.pow(10, a), hi: Math.pow(10, b), ticks: ticks, f: v => (Math.log10(Math.max(v, 1e-300)) - a) / (b - a), lab: v => String(+v.toPrecision(1))};
  }
  if (!(hi > lo)) { lo -= 1; hi += 1; }
  const s = step || niceStep(hi - lo, n);
  if (!raw) { lo = Math.floor(lo / s + 1e-9) * s; hi = Math.ceil(hi / s - 1e-9) * s; }
  const ticks = [];
  for (let v = Math.ceil(lo / s - 1e-9) * s; v <= hi + 1e-9 * s; v += s) ticks.push(v);
  return {lo: lo, hi: hi, ticks: ticks, f: v => (v - lo) / (hi - lo), lab: v => (Math.abs(v) < s / 2 ? 0 : v).toFixed(decimals(s))};
}
// A plot: frame, nice ticks, clip. o: {w, h, x: [lo, hi], y: [lo, hi], equal, xlog, ylog,
// yraw (y range as given), title, xl, yl, ml}. Returns the mapping and the clipped group.
function plot(hostId, o) {
  const host = document.getElementById(hostId);
  host.textContent = '';
  const W = o.w || 600, H = o.h || 320, m = {l: o.ml || 56, r: 14, t: 26, b: 40};
  const pw = W - m.l - m.r, ph = H - m.t - m.b;
  let ax, ay;
  if (o.equal) {
    let [x0, x1] = o.x, [y0, y1] = o.y;
    const s = Math.max((x1 - x0) / pw, (y1 - y0) / ph), cx = (x0 + x1) / 2, cy = (y0 + y1) / 2;
    const step = niceStep(Math.max(s * pw, s * ph), 6);
    ax = axis(cx - s * pw / 2, cx + s * pw / 2, 6, false, true, step);
    ay = axis(cy - s * ph / 2, cy + s * ph / 2, 6, false, true, step);
  } else {
    ax = axis(o.x[0], o.x[1], 6, o.xlog, false);
    ay = axis(o.y[0], o.y[1], 5, o.ylog, o.yraw);
  }
  const X = v => m.l + ax.f(v) * pw, Y = v => m.t + ph - ay.f(v) * ph;
  const svg = el('svg', {width: W, height: H, viewBox: '0 0 ' + W + ' ' + H, class: 'plot', id: 's-' + hostId}, host);
  el('rect', {class: 'plot-area', x: m.l, y: m.t, width: pw, height: ph, fill: '#fff', stroke: '#999'}, svg);
  for (const v of ax.ticks) {
    el('line', {class: 'grid', x1: X(v), x2: X(v), y1: m.t, y2: m.t + ph}, svg);
    txt(svg, X(v), m.t + ph + 14, ax.lab(v), {'text-anchor': 'middle'});
  }
  for (const v of ay.ticks) {
    el('line', {class: 'grid', x1: m.l, x2: m.l + pw, y1: Y(v), y2: Y(v)}, svg);
    if (!o.yraw) txt(svg, m.l - 4, Y(v) + 4, ay.lab(v), {'text-anchor': 'end'});
  }
  txt(svg, m.l, 17, o.title, {class: 'ttl'});
  txt(svg, m.l + pw / 2, H - 6, o.xl, {'text-anchor': 'middle'});
  txt(svg, 12, m.t + ph / 2, o.yl, {'text-anchor': 'middle', transform: 'rotate(-90 12 ' + (m.t + ph / 2) + ')'});
  const cp = el('clipPath', {id: 'c-' + hostId}, svg);
  el('rect', {x: m.l, y: m.t, width: pw, height: ph}, cp);
  const g = el('g', {'clip-path': 'url(#c-' + hostId + ')'}, svg);
  return {svg: svg, g: g, X: X, Y: Y, x0: ax.lo, x1: ax.hi, y0: ay.lo, y1: ay.hi, m: m, pw: pw, ph: ph, ax: ax};
}
function poly(p, pts, attrs) {
  let s = '';
  for (const q of pts) if (q[0] !== null && q[1] !== null) s += p.X(q[0]).toFixed(1) + ',' + p.Y(q[1]).toFixed(1) + ' ';
  return el('polyline', Object.assign({points: s, fill: 'none', 'stroke-width': 1.5}, attrs), p.g);
}
function estLine(p, e, pts, extra) {
  const a = {stroke: e.c, 'data-id': e.id, class: 'ln'};
  if (e.d) a['stroke-dasharray'] = e.d;
  return poly(p, pts, Object.assign(a, extra || {}));
}
function key(id, items) {
  const k = document.getElementById(id);
  if (k) k.innerHTML = items.join('');
}
function bounds(sets) {
  let b = [Infinity, -Infinity, Infinity, -Infinity];
  for (const a of sets) for (let i = 0; i + 1 < a.length; i += 2) {
    b[0] = Math.min(b[0], a[i]); b[1] = Math.max(b[1], a[i]); b[2] = Math.min(b[2], a[i + 1]); b[3] = Math.max(b[3], a[i + 1]);
  }
  if (!isFinite(b[0])) b = [0, 1, 0, 1];
  const pad = 0.04 * Math.max(b[1] - b[0], b[3] - b[2]) + 0.5;
  return [b[0] - pad, b[1] + pad, b[2] - pad, b[3] + pad];
}
function drawTruth(p, small) {
  if (D.checkpoints) {
    for (const q of pairs(D.truth, 2)) el('circle', {cx: p.X(q[0]), cy: p.Y(q[1]), r: small ? 1.5 : 3, fill: small ? '#999' : '#000', class: 'truth'}, p.g);
  } else {
    poly(p, pairs(D.truth, 2), {stroke: small ? '#bbb' : '#000', 'stroke-width': small ? 3 : 2.2, class: 'truth'});
  }
}
function drawAnchors(p) {
  for (const a of D.anchors) {
    const x = p.X(a[1]), y = p.Y(a[2]);
    el('polygon', {class: 'anchor', points: x + ',' + (y - 6) + ' ' + (x - 5) + ',' + (y + 4) + ' ' + (x + 5) + ',' + (y + 4), fill: '#f0c000', stroke: '#000'}, p.g);
    txt(p.g, x + 6, y - 4, String(a[0]), {'font-size': 9});
  }
}

function drawTrajectories() {
  const v = visible();
  const fit = bounds([D.truth, D.anchors.flatMap(a => [a[1], a[2]])].concat(v.map(e => e.tr)));
  const b = zoom || fit;
  const p = plot('p-traj', {w: 600, h: 520, x: [b[0], b[1]], y: [b[2], b[3]], equal: true,
    title: 'Trajectories', xl: 'x east [m]', yl: 'y north [m]'});
  drawTruth(p, false);
  for (const e of v) estLine(p, e, pairs(e.tr, 2));
  drawAnchors(p);
  key('k-traj', [D.checkpoints ? '<span>&#9679; truth checkpoints</span>' : '<span><b>&#9473;</b> truth</span>',
    D.anchors.length ? '<span style="color:#c09000">&#9650;</span> anchors' : '']);
  enableZoom(p, fit);
}
function enableZoom(p, fit) {
  const svg = p.svg;
  const toData = ev => {
    const r = svg.getBoundingClientRect();
    const sx = ev.clientX - r.left, sy = ev.clientY - r.top;
    return [p.x0 + (sx - p.m.l) / p.pw * (p.x1 - p.x0), p.y0 + (p.m.t + p.ph - sy) / p.ph * (p.y1 - p.y0)];
  };
  svg.addEventListener('wheel', ev => {
    ev.preventDefault();
    const c = toData(ev), f = ev.deltaY > 0 ? 1.25 : 0.8;
    zoom = [c[0] + (p.x0 - c[0]) * f, c[0] + (p.x1 - c[0]) * f, c[1] + (p.y0 - c[1]) * f, c[1] + (p.y1 - c[1]) * f];
    drawTrajectories();
    highlight(pinned);
  }, {passive: false});
  svg.addEventListener('mousedown', ev => {
    const start = toData(ev), z0 = [p.x0, p.x1, p.y0, p.y1];
    const move = mv => {
      const c = toData(mv), dx = c[0] - start[0], dy = c[1] - start[1];
      zoom = [z0[0] - dx, z0[1] - dx, z0[2] - dy, z0[3] - dy];
      const t = 'translate(' + (dx / (p.x1 - p.x0) * p.pw) + ',' + (-dy / (p.y1 - p.y0) * p.ph) + ')';
      p.g.firstChild && p.g.childNodes.forEach(n => n.setAttribute('transform', t));
    };
    const up = () => { window.removeEventListener('mousemove', move); window.removeEventListener('mouseup', up); drawTrajectories(); highlight(pinned); };
    window.addEventListener('mousemove', move);
    window.addEventListener('mouseup', up);
  });
  svg.addEventListener('dblclick', () => { zoom = null; drawTrajectories(); highlight(pinned); });
}

// The error axis: up to 1.2 x the largest 95th percentile shown (spikes above are clipped);
// logarithmic (from the smallest 5th percentile shown) while "log error axis" is ticked, by
// default when the 95th percentiles shown span more than a factor of 10.
const logBox = document.getElementById('logerr');
{
  const p95 = E.map(e => e.q[95]).filter(x => x > 0);
  logBox.checked = p95.length > 1 && Math.max(...p95) > 10 * Math.min(...p95);
}
function errorTop(v) { return Math.max(0.1, 1.2 * Math.max(0, ...v.map(e => e.q[95]))); }
function errorAxis(v) {
  const top = errorTop(v);
  if (!logBox.checked) return {r: [0, top], log: false};
  const q5 = v.map(e => e.q[5]).filter(x => x > 0);
  return {r: [Math.max(1e-3, 0.8 * Math.min(top / 10, ...q5)), top], log: true};
}
function drawErrorSeries(hostId, col, title, xl) {
  const v = visible().filter(e => e.er.length > 0);
  let xa = Infinity, xb = -Infinity;
  for (const e of v) for (let i = col; i < e.er.length; i += 5) if (e.er[i] !== null) { xa = Math.min(xa, e.er[i]); xb = Math.max(xb, e.er[i]); }
  if (!isFinite(xa)) { xa = 0; xb = 1; }
  const ea = errorAxis(v);
  const p = plot(hostId, {x: [xa, xb], y: ea.r, ylog: ea.log, title: title, xl: xl, yl: 'error [m]'});
  for (const e of v) estLine(p, e, pairs(e.er, 5).map(q => [q[col], q[2]]));
  if (col === 0 && D.pcrb) {
    const b = pairs(D.pcrb.ts, 3);
    poly(p, b.map(q => [q[0], q[1]]), {stroke: '#000', 'stroke-dasharray': '6,3', 'stroke-width': 1.2, class: 'pcrb'});
    poly(p, b.map(q => [q[0], q[2]]), {stroke: '#000', 'stroke-dasharray': '2,3', 'stroke-width': 1.2, class: 'pcrb'});
    key('k-time', ['<span>- - - PCRB smoother &radic;tr B(t)</span>', '<span>&middot;&middot;&middot; PCRB filter</span>',
      D.runs > 1 ? '<span>curves: the first run</span>' : '']);
  }
}
function drawCdf() {
  const v = visible();
  const ea = errorAxis(v);
  const p = plot('p-cdf', {x: ea.r, xlog: ea.log, y: [0, 1], title: 'Error CDF', xl: 'error [m]', yl: 'fraction of points'});
  for (const e of v) estLine(p, e, e.q.map((x, i) => [x, i / 100]));
}
function drawBox() {
  const v = visible().slice().sort((a, b) => a.q[50] - b.q[50] || (a.id < b.id ? -1 : 1));
  const rowH = 18, H = 70 + rowH * Math.max(1, v.length);
  const ea = errorAxis(v);
  const p = plot('p-box', {w: 600, h: H, ml: 150, x: ea.r, xlog: ea.log, y: [0, Math.max(1, v.length)], yraw: true, title: 'Error distribution', xl: 'error [m]', yl: ''});
  v.forEach((e, i) => {
    const y = p.Y(v.length - i - 0.5), h = rowH * 0.6;
    txt(p.svg, p.m.l - 6, y + 4, e.id, {'text-anchor': 'end', fill: e.c});
    el('line', {x1: p.X(e.q[5]), x2: p.X(e.q[95]), y1: y, y2: y, stroke: e.c, 'data-id': e.id}, p.g);
    el('rect', {x: p.X(e.q[25]), y: y - h / 2, width: Math.max(1, p.X(e.q[75]) - p.X(e.q[25])), height: h, fill: e.c, 'fill-opacity': 0.35, stroke: e.c, 'data-id': e.id}, p.g);
    el('line', {x1: p.X(e.q[50]), x2: p.X(e.q[50]), y1: y - h / 2, y2: y + h / 2, stroke: '#000', 'stroke-width': 2, 'data-id': e.id}, p.g);
    el('circle', {cx: p.X(e.rmse), cy: y, r: 2.5, fill: '#000', 'data-id': e.id}, p.g);
  });
}
function drawEllipses() {
  const host = document.getElementById('f-ell');
  if (!ellEst.length) { host.style.display = 'none'; return; }
  const e = E.find(x => x.id === ellId) || ellEst[0];
  const centres = pairs(e.el, 5);
  const b = bounds([D.truth, e.tr, centres.flatMap(c => [c[0] - c[2], c[1] - c[2], c[0] + c[2], c[1] + c[2]])]);
  const p = plot('p-ell', {w: 600, h: 480, x: [b[0], b[1]], y: [b[2], b[3]], equal: true,
    title: '2\u03C3 position ellipses: ' + e.id, xl: 'x east [m]', yl: 'y north [m]'});
  drawTruth(p, true);
  estLine(p, e, pairs(e.tr, 2));
  const s = p.pw / (p.x1 - p.x0);
  for (const c of centres) {
    el('ellipse', {cx: p.X(c[0]), cy: p.Y(c[1]), rx: Math.max(0.5, c[2] * s), ry: Math.max(0.5, c[3] * s), fill: e.c,
      'fill-opacity': 0.12, stroke: e.c, transform: 'rotate(' + (-c[4]) + ' ' + p.X(c[0]) + ' ' + p.Y(c[1]) + ')', 'data-id': e.id}, p.g);
  }
  key('k-ell', ['<span>every k-th pose (at most 30); truth in grey</span>']);
}
function drawNees() {
  const v = visible().filter(e => e.ne.length > 0);
  const host = document.getElementById('f-nees');
  if (!E.some(e => e.ne.length > 0)) { host.style.display = 'none'; return; }
  let lo = 0.05, hi = 8;
  for (const e of v) for (let i = 1; i < e.ne.length; i += 2) if (e.ne[i] > 0) { lo = Math.min(lo, e.ne[i]); hi = Math.max(hi, e.ne[i]); }
  let ta = Infinity, tb = -Infinity;
  for (const e of v) { ta = Math.min(ta, e.ne[0]); tb = Math.max(tb, e.ne[e.ne.length - 2]); }
  if (!isFinite(ta)) { ta = 0; tb = 1; }
  const p = plot('p-nees', {x: [ta, tb], y: [Math.max(lo, 1e-4), Math.min(hi, 1e8)], ylog: true, title: 'Position NEES', xl: 't [s]', yl: 'NEES'});
  // 95 % band of chi-square with 2 degrees of freedom: [0.0506, 7.38]; its mean is 2.
  el('rect', {x: p.m.l, width: p.pw, y: p.Y(7.378), height: p.Y(0.0506) - p.Y(7.378), fill: '#2a8a2a', 'fill-opacity': 0.1}, p.g);
  poly(p, [[p.x0, 2], [p.x1, 2]], {stroke: '#2a8a2a', 'stroke-dasharray': '4,3', 'stroke-width': 1});
  for (const e of v) estLine(p, e, pairs(e.ne, 2));
  key('k-nees', ['<span style="color:#2a8a2a">&#9632; &chi;&sup2;(2) 95 % band [0.05, 7.38], - - mean 2</span>',
    D.runs > 1 ? '<span>the first run</span>' : '']);
}
function drawRuns() {
  const v = visible().filter(e => e.runs && e.runs.length > 1);
  const host = document.getElementById('f-runs');
  if (!E.some(e => e.runs && e.runs.length > 1)) { host.style.display = 'none'; return; }
  const stats = v.map(e => { const r = e.runs.slice().sort((a, b) => a - b), q = f => r[Math.round(f * (r.length - 1))]; return {e: e, q: [q(0), q(0.25), q(0.5), q(0.75), q(1)]}; })
    .sort((a, b) => a.q[2] - b.q[2] || (a.e.id < b.e.id ? -1 : 1));
  const rowH = 18, H = 70 + rowH * Math.max(1, stats.length);
  const top = Math.max(D.pcrb && D.pcrb.rmse ? D.pcrb.rmse * 1.1 : 0.1, ...stats.map(s => s.q[4] * 1.05));
  const p = plot('p-runs', {w: 600, h: H, ml: 150, x: [0, top], y: [0, Math.max(1, stats.length)], yraw: true, title: 'RMSE over the ' + D.runs + ' runs', xl: 'RMSE of a run [m]', yl: ''});
  stats.forEach((s, i) => {
    const y = p.Y(stats.length - i - 0.5), h = rowH * 0.6, e = s.e;
    txt(p.svg, p.m.l - 6, y + 4, e.id, {'text-anchor': 'end', fill: e.c});
    el('line', {x1: p.X(s.q[0]), x2: p.X(s.q[4]), y1: y, y2: y, stroke: e.c, 'data-id': e.id}, p.g);
    el('rect', {x: p.X(s.q[1]), y: y - h / 2, width: Math.max(1, p.X(s.q[3]) - p.X(s.q[1])), height: h, fill: e.c, 'fill-opacity': 0.35, stroke: e.c, 'data-id': e.id}, p.g);
    el('line', {x1: p.X(s.q[2]), x2: p.X(s.q[2]), y1: y - h / 2, y2: y + h / 2, stroke: '#000', 'stroke-width': 2, 'data-id': e.id}, p.g);
  });
  const items = ['<span>box: quartiles of the per-run RMSE, whiskers: min and max</span>'];
  if (D.pcrb && D.pcrb.rmse) {
    el('line', {x1: p.X(D.pcrb.rmse), x2: p.X(D.pcrb.rmse), y1: p.m.t, y2: p.m.t + p.ph, stroke: '#000', 'stroke-dasharray': '6,3', class: 'pcrb'}, p.g);
    items.push('<span>- - - PCRB (smoother) ' + D.pcrb.rmse.toFixed(3) + ' m</span>');
  }
  key('k-runs', items);
}
// Error colour map (viridis, 5 stops) from 0 to `top`.
const VIR = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
function errColour(x) {
  const f = Math.min(1, Math.max(0, x)) * (VIR.length - 1), i = Math.min(VIR.length - 2, Math.floor(f)), t = f - i;
  const c = VIR[i].map((a, j) => Math.round(a + t * (VIR[i + 1][j] - a)));
  return 'rgb(' + c.join(',') + ')';
}
function drawApe() {
  const grid = document.getElementById('ape-grid');
  grid.textContent = '';
  const v = visible().filter(e => e.er.length > 0);
  const ea = errorAxis(v), ax = axis(ea.r[0], ea.r[1], 4, ea.log, false);
  const frac = x => Math.min(1, Math.max(0, ax.f(Math.max(x, ax.lo))));
  let bar = '<span>error [m]' + (ea.log ? ' (log scale)' : '') + ': </span>';
  for (const x of ax.ticks) bar += '<span style="background:' + errColour(frac(x)) + ';color:' + (frac(x) > 0.6 ? '#000' : '#fff') + ';padding:0 6px">' + ax.lab(x) + '</span>';
  key('k-ape', [bar + ' <span>(the same scale in every panel)</span>']);
  for (const e of v) {
    const div = document.createElement('div');
    div.id = 'ape-' + e.id;
    grid.appendChild(div);
    const b = bounds([D.truth, e.tr]);
    const p = plot(div.id, {w: 250, h: 250, ml: 40, x: [b[0], b[1]], y: [b[2], b[3]], equal: true, title: e.id, xl: 'x [m]', yl: 'y [m]'});
    drawTruth(p, true);
    const q = pairs(e.er, 5);
    for (let i = 0; i < q.length; i++) {
      const c = errColour(frac(q[i][2]));
      if (!D.checkpoints && i + 1 < q.length) {
        el('line', {x1: p.X(q[i][3]), y1: p.Y(q[i][4]), x2: p.X(q[i + 1][3]), y2: p.Y(q[i + 1][4]), stroke: c, 'stroke-width': 2.5}, p.g);
      } else {
        el('circle', {cx: p.X(q[i][3]), cy: p.Y(q[i][4]), r: 2.5, fill: c}, p.g);
      }
    }
  }
}

function legend() {
  const L = document.getElementById('legend');
  let h = '<div class="fl">estimators (click: show/hide)</div>', fam = -1;
  for (const e of E.slice().sort((a, b) => a.f - b.f)) {
    if (e.f !== fam) { fam = e.f; h += '<div class="fl">' + D.families[fam] + '</div>'; }
    h += '<div class="it' + (hidden.has(e.id) ? ' off' : '') + '" data-lid="' + e.id + '"><svg width="30" height="10"><line x1="0" y1="5" x2="30" y2="5" stroke="' + e.c +
      '" stroke-width="2.5"' + (e.d ? ' stroke-dasharray="' + e.d + '"' : '') + '/></svg> <span class="sw" style="background:' + e.c + '"></span>' + e.id + '</div>';
  }
  L.innerHTML = h;
  L.querySelectorAll('div.it').forEach(d => {
    const id = d.getAttribute('data-lid');
    d.addEventListener('click', () => toggle(id));
    d.addEventListener('mouseenter', () => highlight(id));
    d.addEventListener('mouseleave', () => highlight(pinned));
  });
}
let drawMs = 0;
function drawAll() {
  const t0 = performance.now();
  legend();
  drawTrajectories();
  drawErrorSeries('p-time', 0, 'Horizontal error vs time', 't [s]');
  drawErrorSeries('p-dist', 1, 'Horizontal error vs distance walked', 'distance walked (truth) [m]');
  drawCdf(); drawBox(); drawEllipses(); drawNees(); drawRuns(); drawApe();
  document.querySelectorAll('#results tr.est').forEach(r => {
    const off = hidden.has(r.getAttribute('data-id'));
    r.classList.toggle('off', off);
    r.querySelector('input.tog').checked = !off;
  });
  highlight(pinned);
  drawMs = Math.round(performance.now() - t0);
  check();
}
function toggle(id) { if (hidden.has(id)) hidden.delete(id); else hidden.add(id); drawAll(); }
function highlight(id) {
  document.body.classList.toggle('hl-on', !!id);
  document.querySelectorAll('[data-id]').forEach(n => n.classList.toggle('hl', n.getAttribute('data-id') === id));
}

// The table: sort by a column (within families while grouped), toggles, highlight.
let sortCol = -1, sortDir = 1;
function sortTable() {
  const tb = document.querySelector('#results tbody');
  const rows = Array.from(tb.querySelectorAll('tr.est'));
  const fams = Array.from(tb.querySelectorAll('tr.fam'));
  const grouped = document.getElementById('group').checked;
  const val = r => {
    if (sortCol <= 0) return sortCol < 0 ? +r.getAttribute('data-k') : r.getAttribute('data-id');
    const v = r.children[sortCol].getAttribute('data-v');
    return v === '' ? null : +v;
  };
  rows.sort((a, b) => {
    if (grouped && a.getAttribute('data-f') !== b.getAttribute('data-f')) return a.getAttribute('data-f') - b.getAttribute('data-f');
    const x = val(a), y = val(b);
    if (x === null || y === null) return (x === null) - (y === null);
    return (x < y ? -1 : x > y ? 1 : 0) * sortDir;
  });
  tb.textContent = '';
  let f = null;
  for (const r of rows) {
    if (grouped && r.getAttribute('data-f') !== f) {
      f = r.getAttribute('data-f');
      tb.appendChild(fams.find(x => x.getAttribute('data-f') === f));
    }
    tb.appendChild(r);
  }
  if (!grouped) fams.forEach(x => { x.remove(); tb.appendChild(x); x.style.display = 'none'; });
  else fams.forEach(x => { x.style.display = ''; });
  document.querySelectorAll('#results thead th').forEach((th, i) => {
    th.classList.toggle('asc', i === sortCol && sortDir > 0);
    th.classList.toggle('desc', i === sortCol && sortDir < 0);
  });
}
document.querySelectorAll('#results thead th').forEach((th, i) => th.addEventListener('click', () => {
  sortDir = sortCol === i ? -sortDir : 1; sortCol = i; sortTable();
}));
document.getElementById('group').addEventListener('change', sortTable);
logBox.addEventListener('change', drawAll);
document.getElementById('all-on').addEventListener('click', () => { hidden.clear(); drawAll(); });
document.getElementById('all-off').addEventListener('click', () => { E.forEach(e => hidden.add(e.id)); drawAll(); });
document.querySelectorAll('#results tr.est').forEach(r => {
  const id = r.getAttribute('data-id');
  r.addEventListener('mouseenter', () => { r.classList.add('hl'); highlight(id); });
  r.addEventListener('mouseleave', () => { r.classList.remove('hl'); highlight(pinned); });
  r.addEventListener('click', ev => {
    if (ev.target.classList.contains('tog')) { toggle(id); return; }
    pinned = pinned === id ? null : id; highlight(pinned);
  });
});
const sel = document.getElementById('ell-sel');
for (const e of ellEst) { const o = document.createElement('option'); o.value = o.textContent = e.id; sel.appendChild(o); }
sel.addEventListener('change', () => { ellId = sel.value; drawEllipses(); highlight(pinned); });

// Layout self-check (see the top of report_script.h).
function check() {
  const colours = {};
  for (const e of E) {
    const n = document.querySelector('#s-p-traj polyline[data-id="' + e.id + '"]');
    colours[e.id] = n ? n.getAttribute('stroke') : null;
  }
  const drawn = Object.values(colours).filter(c => c);
  const boxes = Array.from(document.querySelectorAll('.legend')).filter(n => n.offsetParent !== null || n.id === 'legend')
    .map(n => [n.id || n.className, n.getBoundingClientRect()]).filter(b => b[1].width > 0 && b[1].height > 0);
  const areas = Array.from(document.querySelectorAll('.plot-area')).map(n => [n.closest('svg').id, n.getBoundingClientRect()]);
  const overlaps = [];
  for (const [ln, l] of boxes) for (const [pn, a] of areas) {
    const w = Math.min(l.right, a.right) - Math.max(l.left, a.left), h = Math.min(l.bottom, a.bottom) - Math.max(l.top, a.top);
    if (w > 0.5 && h > 0.5) overlaps.push(ln + ' over ' + pn);
  }
  document.getElementById('wg-check').textContent = JSON.stringify({
    estimators: E.length, colours: colours, distinct_colours: new Set(drawn).size,
    legend_boxes: boxes.length, plot_areas: areas.length, overlaps: overlaps, draw_ms: drawMs});
}
drawAll();
})();
)JS";

}  // namespace walkgraph::report

#endif  // WALKGRAPH_SRC_REPORT_REPORT_SCRIPT_H_
