/* coadapt dashboard: the pages of one run, one grid and a comparison of runs (the runs page
   and the helpers are in dashboard.js). Values from the store are set as text only. */
"use strict";

(function () {
  const D = window.CoDashboard, el = D.el, main = document.getElementById("main");
  const pathId = () => decodeURIComponent(location.pathname.split("/")[2] || "");

  function chart(spec) {
    const box = el("div", { class: "chart-box" });
    if (spec.series.some(s => s.points && s.points.length)) window.CoChart.plot(box, spec);
    else box.appendChild(el("p", { class: "empty", text: (spec.title || "chart") + ": " + (spec.empty || "nothing recorded yet") }));
    return box;
  }

  // as the run folder's convergence.png (report_figures): the best so far as a step line, the
  // final check ± SE after it (by the check's own interactions), the nominal design's cost in
  // the same check as a dotted line
  function convergenceSeries(c, label, color) {
    const out = [{ label: label, kind: "step", color: color, points: c.x.map((x, i) => [x, c.y[i]]) }];
    if (c.final && c.x.length) {
      const end = c.x[c.x.length - 1] + (c.final.interactions || 0);
      out.push({ label: "final check ± SE (fresh scenarios)", kind: "points", shape: "square", color: color, filled: false,
        points: [[end, c.final.cost]], err: [c.final.se] });
      if (c.final.nominal !== null && c.final.nominal !== undefined) {
        out.push({ label: "nominal design (final check)", kind: "line", dash: "2,4", color: "#555",
          points: [[c.x[0], c.final.nominal], [end, c.final.nominal]] });
      }
    }
    return out;
  }

  // what the learner measured, one chart per unit (their scales differ tenfold)
  function measureCharts(t, training, measures) {
    return measures.map(m => chart({ title: m.title, xLabel: "training interactions (cumulative)", yLabel: m.unit, legend: "below",
      empty: "the phases recorded no " + m.series.map(s => s[1]).join(" or "),
      series: m.series.map(([key, name]) => ({ label: name + " (" + m.unit + ")", kind: "line", markers: true,
        points: t.map((p, i) => [training[i][0], p[key]]).filter(q => q[1] !== null && q[1] !== undefined) })).filter(s => s.points.length) }));
  }

  function designChart(data) {
    const names = data.design_names, first = data.run.objectives[0];
    if (names.length < 1 || !first) return chart({ title: "designs", series: [] });
    const xy = e => [e.design[0], names.length > 1 ? e.design[1] : e.costs[first]];
    const kinds = [["real", "circle"], ["surrogate", "square"]];
    return chart({
      title: "Evaluated designs, coloured by " + first + " cost (circle: real, square: surrogate)",
      xLabel: names[0] + (data.design_units[0] ? " [" + data.design_units[0] + "]" : ""),
      yLabel: names.length > 1 ? names[1] + (data.design_units[1] ? " [" + data.design_units[1] + "]" : "") : first + " cost",
      colorLabel: first + " cost", legend: true,
      series: kinds.map(([kind, shape]) => {
        const rows = data.evaluations.filter(e => e.kind === kind && e.design.length);
        return { label: kind, kind: "points", shape: shape, points: rows.map(xy), values: rows.map(e => e.costs[first]) };
      }),
    });
  }

  function paretoBlock(p) {
    if (!p) return [];
    const [o1, o2] = p.objectives;
    const err = p.front_se ? p.front_se.map(s => s[1]) : null, errX = p.front_se ? p.front_se.map(s => s[0]) : null;
    const series = [
      { label: "evaluated (in-run estimates)", kind: "points", color: "#999", size: 3, points: p.evaluated },
      { label: "front ± SE", kind: "line", markers: true, color: "#d62728", points: p.front, err: err, errX: errX },
    ];
    if (p.nominal) series.push({ label: "nominal", kind: "points", shape: "diamond", color: "#000", points: [p.nominal] });
    return [el("h2", { text: "Pareto front" }),
      D.facts([["front designs", p.front_designs, "front_designs"], ["hypervolume", p.hypervolume, "hypervolume"], ["front from", p.source, "front_source"]], "pareto"),
      chart({ title: "Pareto front", xLabel: o1 + " cost", yLabel: o2 + " cost", series: series }),
      D.table(["pick", ...p.objectives.map(o => o + " cost"), "design"],
        p.front.map((c, i) => [i, ...c.map(v => Number(v).toPrecision(5)), p.designs[i].map(v => Number(v).toFixed(3)).join(", ")]), { id: "front" })];
  }

  function summaryBlock(data) {
    const r = data.run, rep = data.report;
    return D.facts([
      ["state", r.status, "status"], ["progress", D.progressText(data.progress), "progress"],
      ["robot", r.robot], ["simulator", r.simulator], ["method", r.method], ["optimizer", r.optimizer],
      ["objectives", r.objectives.join(", "), "objectives"], ["terrain", r.terrain], ["seed", r.seed], ["preset", r.preset],
      ["grid", r.grid_id ? D.link(D.gridHref(r.grid_id), r.grid_id + " · " + (r.cell || "")) : "–", "grid"],
      ["best design", D.designText(rep.best_design), "best_design"], ["best cost", rep.best_cost, "best_cost"],
      ["nominal cost", rep.nominal_cost, "nominal_cost"], ["improvement ± SE", rep.improvement, "improvement"],
      ["improvement (plain mean)", rep.improvement_plain, "improvement_plain"],
      ["fall rate best / nominal", rep.fall_rates, "fall_rates"], ["fall-rate difference", rep.fall_rate_difference, "fall_rate_difference"],
      ["with specialists", data.verification, "verification"],
      ["numerics", data.numerics, "numerics"], ["warnings", data.warnings.join("; ") || "none", "warnings"],
      ["started", D.when(r.created_at), "created"], ["last row", D.when(r.updated_at), "updated"],
      ["code", (r.code_version || "?") + " " + (r.git_commit || ""), "code"],
    ], "summary");
  }

  function evaluationsBlock(data) {
    const names = data.design_names, objectives = data.run.objectives;
    const counts = Object.entries(data.counts).map(([k, n]) => `${n} ${k}`).join(", ");
    return [el("h2", { text: "Evaluations" }), el("p", { id: "eval-count", "data-rows": data.evaluations.length, text: `${D.count(data.evaluations.length, "row")}: ${counts || "none yet"}` }),
      el("details", { class: "scroll", id: "rows-box", open: data.evaluations.length <= 200 }, el("summary", { text: "every row" }), D.table(["outer", "inner", "idx", "kind", ...names, ...objectives.map(o => o + " cost"), "surrogate error"],
        data.evaluations.map(e => [e.outer, e.inner, e.idx, e.kind, ...names.map((_, i) => e.design[i] === undefined ? "" : Number(e.design[i]).toFixed(4)),
          ...objectives.map(o => e.costs[o] === undefined || e.costs[o] === null ? "" : Number(e.costs[o]).toPrecision(5)),
          Object.entries(e.surrogate_error).map(([k, v]) => k + " " + Number(v).toPrecision(3)).join(", ")]), { id: "evaluations" }))];
  }

  function filesBlock(data) {
    const id = data.run.id, out = [el("h2", { text: "Run folder" })];
    if (data.folder) out.push(el("p", { class: "warning", id: "folder-state", text: data.folder }));
    if (data.files.includes("best_vs_nominal.gif")) out.push(el("img", { src: D.fileHref(id, "best_vs_nominal.gif"), alt: "best design beside the nominal one", class: "gif" }));
    for (const png of data.files.filter(f => f.endsWith(".png"))) out.push(el("img", { src: D.fileHref(id, png), alt: png + " as the run drew it", class: "gif" }));
    if (data.files.length) out.push(el("ul", { id: "files" }, data.files.map(f => el("li", {}, D.link(D.fileHref(id, f), f)))));
    return out;
  }

  async function runPage() {
    const data = await D.getJSON("/api/run/" + encodeURIComponent(pathId()));
    // a live redraw keeps what the reader opened or closed
    const kept = new Map([...main.querySelectorAll("details[id]")].map(d => [d.id, d.open]));
    const c = data.convergence, t = data.training, firstObjective = data.run.objectives[0] || "cost";
    const surrogate = [...new Set(data.surrogate_error.map(s => s.objective))].map(o => ({ label: o, kind: "points",
      points: data.surrogate_error.filter(s => s.objective === o).map(s => [s.outer, s.percent]) }));
    let steps = 0;
    const training = t.map(p => [steps += p.steps, p.final_reward]);
    main.replaceChildren(
      el("h1", { id: "run-id", text: data.run.id }), summaryBlock(data),
      el("h2", { text: "Charts" }),
      el("div", { class: "charts" },
        chart({ title: "Convergence: best in-run " + firstObjective + " cost so far", xLabel: "environment interactions", yLabel: c.y_label || firstObjective + " cost",
          legend: "below", empty: c.note, series: convergenceSeries(c, "in-run best (own scenarios)", "#1f77b4") }),
        designChart(data),
        chart({ title: "Surrogate error by round (surrogate − real, % of real)", xLabel: "outer iteration", yLabel: "relative error (%)", series: surrogate }),
        chart({ title: "Training phases: final mean reward", xLabel: "training interactions (cumulative)", yLabel: "mean reward per step", series: [{ label: "phase", kind: "line", markers: true, points: training }] }),
        ...measureCharts(t, training, data.training_measures || [])),
      ...paretoBlock(data.pareto), ...filesBlock(data),
      el("h2", { text: "Commands" }), el("pre", { id: "commands", text: data.commands.resume + "\n" + data.commands.handoff }),
      ...evaluationsBlock(data),
      el("h2", { text: "Configuration" }),
      el("details", { id: "config-box" }, el("summary", { text: `the run's configuration (${Object.keys(data.config).length} settings)` }),
        el("pre", { id: "config", text: JSON.stringify(data.config, null, 2) })));
    for (const [id, open] of kept) { const d = document.getElementById(id); if (d) d.open = open; }
    D.poll(runPage, data.run.status === "running");
  }

  async function gridPage() {
    const data = await D.getJSON("/api/grid/" + encodeURIComponent(pathId()));
    const states = Object.entries(data.states).map(([s, n]) => `${n} ${s}`).join(", ");
    const parts = [el("h1", { id: "grid-id", text: "Grid " + data.grid.id }), el("p", { id: "cell-states", text: states || "no cells yet" }),
      el("p", {}, D.link("/?grid=" + encodeURIComponent(data.grid.id), "its runs in the runs table")),
      D.table(["cell", "state", "attempts", "ran again", "run", "run state", "last error"], data.cells.map(c => [c.cell,
        el("span", { class: "state " + c.status, text: c.status }), c.attempts, c.ran_again ? "yes" : "", c.run_id ? D.link(D.runHref(c.run_id), c.run_id) : "–", c.run_status, c.last_error]), { id: "cells" })];
    for (const [title, head, rows] of data.tables) parts.push(el("h2", { text: title }), el("div", { class: "scroll" }, D.table(head, rows, { class: "report" })));
    if (data.paper) {
      parts.push(el("h2", { text: "Beside the paper" }), el("p", { class: "reading", text: data.paper.reading }));
      for (const [title, head, rows] of data.paper.tables) {
        parts.push(el("h3", { text: title }), rows.length ? el("div", { class: "scroll" }, D.table(head, rows, { class: "report" }))
          : el("p", { text: "No run of this grid has a cell in this table of the paper." }));
      }
    }
    main.replaceChildren(...parts);
    D.poll(gridPage, data.cells.some(c => c.status === "running" || c.status === "pending"));
  }

  async function comparePage() {
    const ids = new URLSearchParams(location.search).getAll("run");
    const data = await D.getJSON("/api/compare?" + ids.map(i => "run=" + encodeURIComponent(i)).join("&"));
    const runs = data.runs, rows = [
      ["state", r => r.run.status], ["robot", r => r.run.robot], ["method", r => r.run.method], ["optimizer", r => r.run.optimizer],
      ["objectives", r => r.run.objectives.join(", ")], ["terrain", r => r.run.terrain], ["seed", r => r.run.seed],
      ["best design", r => D.designText(r.report.best_design)], ["best cost", r => r.report.best_cost], ["nominal cost", r => r.report.nominal_cost],
      ["improvement ± SE", r => r.report.improvement], ["improvement (plain mean)", r => r.report.improvement_plain],
      ["fall-rate difference", r => r.report.fall_rate_difference], ["designs evaluated", r => r.evaluated], ["warnings", r => r.warnings.join("; ") || "none"]];
    const series = runs.flatMap((r, i) => r.convergence.x.length ? [{ label: r.run.id, kind: "step", color: window.CoChart.color(i), points: r.convergence.x.map((x, k) => [x, r.convergence.y[k]]) }] : []);
    main.replaceChildren(el("h1", { text: "Compare " + D.count(runs.length, "run") }),
      el("div", { class: "scroll" }, D.table(["", ...runs.map(r => D.link(D.runHref(r.run.id), r.run.id))], rows.map(([k, f]) => [k, ...runs.map(f)]), { id: "compare-table" })),
      chart({ title: "Convergence: best in-run cost so far", xLabel: "environment interactions", yLabel: "cost", legend: true, series: series, width: 720 }));
    D.poll(comparePage, runs.some(r => r.run.status === "running"));
  }

  Object.assign(window.CoDashboardPages, { run: runPage, grid: gridPage, compare: comparePage });
})();
