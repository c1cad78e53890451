/* coadapt dashboard pages: runs, a run, a grid, a comparison. Each fetches its JSON from
   /api/... and draws it; every value from the store is written as text (textContent), never
   as markup. A page whose runs are still working fetches again every few seconds (live). */
"use strict";

(function () {
  const POLL_MS = 3000;
  const main = document.getElementById("main");
  const live = document.getElementById("live");
  let timer = null;

  function el(tag, attrs, ...children) {
    const n = document.createElement(tag);
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === "text") n.textContent = String(v);
      else n.setAttribute(k, String(v));
    }
    for (const c of children.flat()) {
      if (c === null || c === undefined) continue;
      n.appendChild(typeof c === "object" ? c : document.createTextNode(String(c)));
    }
    return n;
  }

  // "1 run", "2 runs": a count with its noun, singular for one
  function count(n, noun, plural) { return `${n} ${Number(n) === 1 ? noun : plural || noun + "s"}`; }

  function link(href, content) { return el("a", { href: href, text: content }); }
  function runHref(id) { return "/run/" + encodeURIComponent(id); }
  function gridHref(id) { return "/grid/" + encodeURIComponent(id); }
  function fileHref(id, name) { return "/files/" + encodeURIComponent(id) + "/" + encodeURIComponent(name); }
  function show(v) { return v === null || v === undefined || v === "" ? "–" : String(v); }

  function duration(s) {
    if (s === null || s === undefined || !isFinite(s)) return "?";
    s = Math.round(s);
    const h = Math.floor(s / 3600), m = Math.floor(s % 3600 / 60), r = s % 60;
    return `${h}:${String(m).padStart(2, "0")}:${String(r).padStart(2, "0")}`;
  }

  function when(t) { return t ? new Date(t * 1000).toISOString().replace("T", " ").slice(0, 19) + " UTC" : "–"; }

  function progressText(p) {
    const parts = [];
    if (p.phase) parts.push(p.phase);
    parts.push(Number(p.interactions || 0).toLocaleString("en-US") + " interactions");
    if (p.eta_seconds !== null && p.eta_seconds !== undefined) parts.push("ETA " + duration(p.eta_seconds));
    return parts.join(" · ");
  }

  function designText(cells) {
    return cells.length ? cells.map(c => c[0] + " " + c[1].replace(" (n=1)", "")).join(", ") : "n/a";
  }

  function table(head, rows, attrs) {
    return el("table", attrs || {},
      el("thead", {}, el("tr", {}, head.map(h => (h instanceof Node ? el("th", {}, h) : el("th", { text: h }))))),
      el("tbody", {}, rows.map(r => el("tr", {}, r.map(c => (c instanceof Node ? el("td", {}, c) : el("td", { text: show(c) })))))));
  }

  function facts(pairs, id) {
    return el("table", { class: "facts", id: id },
      el("tbody", {}, pairs.map(([k, v, field]) => el("tr", {}, el("th", { text: k }),
        v instanceof Node ? el("td", { "data-field": field || k }, v) : el("td", { "data-field": field || k, text: show(v) })))));
  }

  async function getJSON(url) {
    const r = await fetch(url, { cache: "no-store" });
    let data;
    try { data = await r.json(); } catch (e) { data = { error: "the dashboard sent no data (" + r.status + ")" }; }
    if (!r.ok) throw new Error(data.error || ("error " + r.status));
    return data;
  }

  function failed(message) {
    main.replaceChildren(el("p", { class: "error", id: "error", text: message }), el("p", {}, link("/", "All runs")));
  }

  function poll(again, running) {
    clearTimeout(timer);
    live.textContent = running ? "live · updated " + new Date().toLocaleTimeString("en-GB") : "";
    if (running) timer = setTimeout(again, POLL_MS);
  }

  // -- runs ---------------------------------------------------------------------------
  const query = new URLSearchParams(location.search);

  function runsControls(data) {
    const q = el("input", { type: "search", name: "q", placeholder: "search id, method, robot…", value: query.get("q") || "" });
    const status = el("select", { name: "status" }, el("option", { value: "", text: "any state" }),
      Object.keys(data.states).sort().map(s => el("option", { value: s, text: `${s} (${data.states[s]})`, selected: s === (query.get("status") || "") })));
    const sort = el("select", { name: "sort" }, ["created", "updated", "improvement", "status", "robot", "method", "optimizer", "objectives", "terrain", "seed", "id"]
      .map(s => el("option", { value: s, text: "sort: " + s, selected: s === (query.get("sort") || "created") })));
    const desc = el("select", { name: "desc" }, el("option", { value: "1", text: "descending" }),
      el("option", { value: "0", text: "ascending", selected: query.get("desc") === "0" }));
    const grid = query.get("grid") ? el("input", { type: "hidden", name: "grid", value: query.get("grid") }) : null;
    return el("form", { method: "get", action: "/", class: "controls" }, q, status, sort, desc, grid, el("button", { type: "submit", text: "Apply" }),
      grid ? el("span", {}, "runs of grid " + query.get("grid") + " · ", link("/", "all runs")) : null);
  }

  function runsTable(rows) {
    const head = ["", "run", "state", "progress", "robot", "method", "optimizer", "objectives", "terrain", "seed", "best design", "improvement ± SE", "fall-rate difference", "warnings"];
    const body = rows.map(r => [
      el("input", { type: "checkbox", class: "pick", value: r.id, "aria-label": "compare " + r.id }),
      link(runHref(r.id), r.id), el("span", { class: "state " + r.status, text: r.status }), progressText(r.progress),
      r.robot, r.method, r.optimizer, r.objectives, r.terrain, r.seed, designText(r.report.best_design),
      r.report.improvement, r.report.fall_rate_difference, r.warnings.join("; ")]);
    return table(head, body, { id: "runs" });
  }

  // "1 run: 1 finished"; a search or filter says how many of the store's runs it shows
  function runCount(data, states) {
    const all = Object.values(data.states).reduce((a, n) => a + n, 0);
    return data.total === all ? `${count(all, "run")}: ${states}` : `${count(data.total, "run")} of ${all} shown (the store: ${states})`;
  }

  async function runsPage() {
    const params = new URLSearchParams(query);
    const data = await getJSON("/api/runs?" + params.toString());
    const states = Object.entries(data.states).map(([s, n]) => `${n} ${s}`).join(", ") || "no runs yet";
    const compare = el("button", { type: "button", id: "compare", text: "Compare selected" });
    compare.addEventListener("click", () => {
      const ids = [...document.querySelectorAll("input.pick:checked")].map(c => "run=" + encodeURIComponent(c.value));
      if (ids.length) location.href = "/compare?" + ids.join("&");
    });
    const pages = el("p", { class: "pages" }, `page ${data.page + 1} of ${data.pages} · `,
      data.page > 0 ? link("?" + withPage(data.page - 1), "previous") : "", " ",
      data.page + 1 < data.pages ? link("?" + withPage(data.page + 1), "next") : "");
    const grids = data.grids.length ? [el("h2", { text: "Grids" }), table(["grid", "cells by state"],
      data.grids.map(g => [link(gridHref(g.id), g.id), Object.entries(g.cells).map(([s, n]) => `${n} ${s}`).join(", ")]), { id: "grids" })] : [];
    main.replaceChildren(el("h1", { text: "Runs" }), el("p", { id: "run-count", text: runCount(data, states) }),
      runsControls(data), compare, runsTable(data.rows), pages, ...grids);
    poll(runsPage, data.rows.some(r => r.status === "running"));
  }

  function withPage(n) { const p = new URLSearchParams(query); p.set("page", n); return p.toString(); }

  window.CoDashboard = { el, count, link, table, facts, getJSON, failed, poll, progressText, designText, show, when, runHref, gridHref, fileHref, duration };

  const pages = { runs: runsPage };
  window.CoDashboardPages = pages;
  document.addEventListener("DOMContentLoaded", () => {
    const page = document.body.dataset.page;
    // a page that could not be read (the store busy, a run not there yet) tries again
    const draw = () => (pages[page] || runsPage)().catch(e => { failed(e.message); poll(draw, false); setTimeout(draw, 2 * POLL_MS); });
    draw();
  });
})();
