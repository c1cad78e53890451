/* coadapt dashboard charts: a small SVG plotting library of its own (no dependency, no
   network). CoChart.plot(container, spec) draws lines, step lines and points with error bars
   on linear axes, points optionally coloured by a value with a colour bar; every label is
   set as text, never as markup. */
"use strict";

(function () {
  const NS = "http://www.w3.org/2000/svg";
  const PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
    "#8c564b", "#e377c2"];
  // a perceptual ramp (dark blue -> yellow) for costs: low cost dark, high cost light
  const RAMP = [[48, 18, 59], [70, 107, 227], [40, 187, 236], [50, 242, 152],
    [164, 252, 60], [237, 208, 58], [251, 128, 34], [122, 4, 3]];

  function node(tag, attrs, parent) {
    const n = document.createElementNS(NS, tag);
    for (const [k, v] of Object.entries(attrs || {})) n.setAttribute(k, String(v));
    if (parent) parent.appendChild(n);
    return n;
  }

  function text(parent, x, y, content, attrs) {
    const t = node("text", Object.assign({ x: x, y: y }, attrs || {}), parent);
    t.textContent = String(content);
    return t;
  }

  function finite(v) { return typeof v === "number" && isFinite(v); }

  function ticks(lo, hi, count) {
    if (!(hi > lo)) { hi = lo + 1; lo = lo - 1; }
    const raw = (hi - lo) / Math.max(1, count);
    const mag = Math.pow(10, Math.floor(Math.log10(raw)));
    const step = [1, 2, 2.5, 5, 10].map(m => m * mag).find(s => s >= raw) || raw;
    const out = [];
    for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
      out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
    }
    return out;
  }

  function label(v) {
    const a = Math.abs(v);
    if (a !== 0 && (a >= 1e5 || a < 1e-3)) return v.toExponential(1);
    return String(Number(v.toPrecision(4)));
  }

  function rampColor(t) {
    t = Math.min(1, Math.max(0, finite(t) ? t : 0));
    const f = t * (RAMP.length - 1), i = Math.min(RAMP.length - 2, Math.floor(f)), w = f - i;
    const c = RAMP[i].map((a, k) => Math.round(a + (RAMP[i + 1][k] - a) * w));
    return "rgb(" + c.join(",") + ")";
  }

  function extent(series, axis) {
    let lo = Infinity, hi = -Infinity;
    for (const s of series) {
      s.points.forEach((p, i) => {
        const v = p[axis], e = axis === 1 && s.err ? (s.err[i] || 0) : 0;
        if (finite(v)) { lo = Math.min(lo, v - (finite(e) ? e : 0)); hi = Math.max(hi, v + (finite(e) ? e : 0)); }
      });
    }
    if (!isFinite(lo)) return [0, 1];
    const pad = (hi - lo) * 0.05 || Math.abs(hi) * 0.05 || 1;
    return [lo - pad, hi + pad];
  }

  function marker(g, shape, x, y, r, color, filled) {
    const style = { fill: filled ? color : "white", stroke: color, "stroke-width": 1.5 };
    if (shape === "square") return node("rect", Object.assign({ x: x - r, y: y - r, width: 2 * r, height: 2 * r }, style), g);
    if (shape === "diamond") {
      const d = `M${x},${y - r * 1.4}L${x + r * 1.4},${y}L${x},${y + r * 1.4}L${x - r * 1.4},${y}Z`;
      return node("path", Object.assign({ d: d }, style), g);
    }
    return node("circle", Object.assign({ cx: x, cy: y, r: r }, style), g);
  }

  function colorBar(svg, W, M, lo, hi, title) {
    const g = node("g", { class: "colorbar" }, svg);
    const x0 = W - M.right + 18, h = 140;
    for (let i = 0; i < 20; i++) {
      node("rect", { x: x0, y: M.top + h - (i + 1) * h / 20, width: 12, height: h / 20 + 0.5, fill: rampColor(i / 19) }, g);
    }
    text(g, x0 + 16, M.top + 8, label(hi), { class: "tick" });
    text(g, x0 + 16, M.top + h, label(lo), { class: "tick" });
    const t = text(g, x0 - 4, M.top + h + 14, title, { class: "axis-title" });
    t.setAttribute("transform", `rotate(90 ${x0 - 4} ${M.top + h + 14})`);
  }

  function plot(container, spec) {
    const colored = spec.series.some(s => s.values);
    // legend "below": under the x axis's title, the chart taller by its lines (for a chart
    // whose lines fill every corner); otherwise inside the plot's top left corner
    const below = spec.legend === "below" ? spec.series.filter(s => s.label).length : 0;
    const W = spec.width || 520, H = (spec.height || 320) + 16 * below;
    const M = { top: 24, right: colored ? 90 : 16, bottom: 44 + 16 * below, left: 64 };
    const svg = node("svg", { viewBox: `0 0 ${W} ${H}`, width: W, height: H, class: "chart", role: "img" });
    if (spec.title) svg.setAttribute("aria-label", spec.title);
    const series = spec.series.filter(s => s.points && s.points.length);
    const [x0, x1] = spec.xRange || extent(series, 0);
    const [y0, y1] = spec.yRange || extent(series, 1);
    const sx = v => M.left + (v - x0) / (x1 - x0 || 1) * (W - M.left - M.right);
    const sy = v => H - M.bottom - (v - y0) / (y1 - y0 || 1) * (H - M.top - M.bottom);
    const axes = node("g", { class: "axes" }, svg);
    for (const t of ticks(x0, x1, 5)) {
      node("line", { x1: sx(t), x2: sx(t), y1: M.top, y2: H - M.bottom, class: "grid" }, axes);
      text(axes, sx(t), H - M.bottom + 16, label(t), { class: "tick", "text-anchor": "middle" });
    }
    for (const t of ticks(y0, y1, 5)) {
      node("line", { x1: M.left, x2: W - M.right, y1: sy(t), y2: sy(t), class: "grid" }, axes);
      text(axes, M.left - 6, sy(t) + 4, label(t), { class: "tick", "text-anchor": "end" });
    }
    node("rect", { x: M.left, y: M.top, width: W - M.left - M.right, height: H - M.top - M.bottom, class: "frame" }, axes);
    text(axes, (M.left + W - M.right) / 2, H - M.bottom + 36, spec.xLabel || "", { class: "axis-title x-title", "text-anchor": "middle" });
    const yt = text(axes, 14, (M.top + H - M.bottom) / 2, spec.yLabel || "", { class: "axis-title y-title", "text-anchor": "middle" });
    yt.setAttribute("transform", `rotate(-90 14 ${(M.top + H - M.bottom) / 2})`);
    if (spec.title) text(svg, M.left, 15, spec.title, { class: "chart-title" });
    let vlo = Infinity, vhi = -Infinity;
    series.forEach(s => (s.values || []).forEach(v => { if (finite(v)) { vlo = Math.min(vlo, v); vhi = Math.max(vhi, v); } }));
    series.forEach((s, k) => {
      const color = s.color || PALETTE[k % PALETTE.length];
      const g = node("g", { class: "series", "data-label": s.label || "" }, svg);
      const pts = s.points.map((p, i) => [p[0], p[1], i]).filter(p => finite(p[0]) && finite(p[1]));
      if (s.kind === "line" || s.kind === "step") {
        let d = "";
        pts.forEach((p, i) => {
          if (i === 0) d += `M${sx(p[0])},${sy(p[1])}`;
          else if (s.kind === "step") d += `H${sx(p[0])}V${sy(p[1])}`;
          else d += `L${sx(p[0])},${sy(p[1])}`;
        });
        node("path", { d: d, fill: "none", stroke: color, "stroke-width": 1.8, "stroke-dasharray": s.dash || "" }, g);
      }
      if (s.kind === "points" || s.markers) {
        for (const p of pts) {
          const e = s.err ? s.err[p[2]] : null, ex = s.errX ? s.errX[p[2]] : null;
          if (finite(e)) {
            node("line", { x1: sx(p[0]), x2: sx(p[0]), y1: sy(p[1] - e), y2: sy(p[1] + e), stroke: color, "stroke-width": 1.5 }, g);
          }
          if (finite(ex)) {
            node("line", { x1: sx(p[0] - ex), x2: sx(p[0] + ex), y1: sy(p[1]), y2: sy(p[1]), stroke: color, "stroke-width": 1.5 }, g);
          }
          const v = s.values ? s.values[p[2]] : null;
          const c = s.values ? rampColor((v - vlo) / ((vhi - vlo) || 1)) : color;
          const m = marker(g, s.shape, sx(p[0]), sy(p[1]), s.size || 4, c, s.filled !== false);
          const tip = node("title", {}, m);
          tip.textContent = `${s.label || ""} (${label(p[0])}, ${label(p[1])})` + (finite(e) ? ` ± ${label(e)}` : "") + (finite(v) ? `: ${label(v)}` : "");
        }
      }
    });
    if (colored && isFinite(vlo)) colorBar(svg, W, M, vlo, vhi, spec.colorLabel || "value");
    const legend = series.filter(s => s.label);
    if (legend.length > 1 || spec.legend) {
      const g = node("g", { class: "legend" }, svg);
      const top = below ? H - M.bottom + 44 : M.top;
      if (!below) {  // a pale box behind the entries, so that a line under them stays legible
        const wide = Math.max(...legend.map(s => String(s.label).length)) * 6.2 + 30;
        node("rect", { x: M.left + 2, y: top + 2, width: Math.min(wide, W - M.left - M.right - 4), height: 16 * legend.length + 4,
          fill: "white", "fill-opacity": 0.85, stroke: "#ddd", class: "legend-box" }, g);
      }
      legend.forEach((s, k) => {
        const y = top + 10 + 16 * k, x = M.left + 10;
        // a series coloured by its values has no colour of its own: its legend marker is grey
        const c = s.values ? "#666" : s.color || PALETTE[spec.series.indexOf(s) % PALETTE.length];
        // a line's entry is a short stretch of it (dashed as it is), a point's its marker
        if (s.kind === "line" || s.kind === "step") {
          node("line", { x1: x - 7, x2: x + 7, y1: y - 4, y2: y - 4, stroke: c, "stroke-width": 1.8, "stroke-dasharray": s.dash || "" }, g);
        }
        if (s.kind === "points" || s.markers) marker(g, s.shape, x, y - 4, 4, c, s.filled !== false);
        text(g, x + 12, y, s.label, { class: "legend-text" });
      });
    }
    container.appendChild(svg);
    return svg;
  }

  window.CoChart = { plot: plot, color: i => PALETTE[i % PALETTE.length] };
})();
