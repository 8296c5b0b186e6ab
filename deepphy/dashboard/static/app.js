// deepphy dashboard: one page, no build step. State arrives over Server-Sent Events
// (/api/events): a "state" event with every run's view, then a message per change with the
// run's new view and the grid cells that changed. Every number comes from the server, which
// computes it with the report code of `deepphy report`.
"use strict";

// Run colours: none of them is a status colour of the cards and the grid (solved green,
// failed red, in-progress blue, pending grey), so a run's line never reads as a status.
const PALETTE = ["#7c3aed", "#ea580c", "#0e7490", "#c026d3", "#854d0e", "#4338ca", "#be185d", "#475569"];

const S = {
  runs: new Map(),     // id -> view
  boards: new Map(),   // id -> leaderboard view of a directory of runs
  colors: new Map(),   // id -> colour, stable in order of arrival
  hidden: new Set(),   // ids left out of the charts
  selected: null,      // run whose table and grid are shown
  chosen: false,       // the selection is the user's (else: the first run, in the server's order)
  grid: null,          // the grid page shown: {run, page, group, tasks, cells, ...}
  page: 0,
  group: "",
  episode: null,       // {run, task, r} of the open episode view
  gridTimer: null,
};

// -- small helpers ---------------------------------------------------------------------

function el(tag, attrs, ...children) {
  const node = tag === "svg" || SVG_TAGS.has(tag)
    ? document.createElementNS("http://www.w3.org/2000/svg", tag) : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k === "class") node.setAttribute("class", v);
    else if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (k === "style" && typeof v === "object") for (const [p, x] of Object.entries(v)) node.style.setProperty(p, x);
    else node.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children.flat(Infinity)) {
    if (c === null || c === undefined || c === false) continue;
    node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return node;
}
const SVG_TAGS = new Set(["g", "line", "polyline", "polygon", "circle", "rect", "text", "title", "path"]);

const pct = (x) => (x === null || x === undefined ? "–" : (100 * x).toFixed(1) + "%");
const num = (x, d = 0) => (x === null || x === undefined ? "–" : Number(x).toLocaleString("en-US", { maximumFractionDigits: d, minimumFractionDigits: d }));
function duration(s) {
  if (s === null || s === undefined || !isFinite(s)) return "–";
  s = Math.round(s);
  if (s < 60) return `${s} s`;
  if (s < 3600) return `${Math.floor(s / 60)} min ${s % 60} s`;
  return `${Math.floor(s / 3600)} h ${Math.floor((s % 3600) / 60)} min`;
}
function colorOf(id) {
  if (!S.colors.has(id)) S.colors.set(id, PALETTE[S.colors.size % PALETTE.length]);
  return S.colors.get(id);
}
// Solved at attempt (or decision) k of K: dark green early, yellow-green late.
function solvedColor(k, K) {
  const t = K > 1 ? (k - 1) / (K - 1) : 0;
  return `hsl(${140 - 75 * t}, ${55 + 15 * t}%, ${32 + 16 * t}%)`;
}

// -- live connection -------------------------------------------------------------------

function connect() {
  const conn = document.getElementById("conn");
  const es = new EventSource("/api/events");
  es.addEventListener("state", (e) => {
    conn.dataset.state = "live"; conn.textContent = "live";
    const state = JSON.parse(e.data);
    S.runs.clear();
    for (const v of state.runs) { colorOf(v.id); S.runs.set(v.id, v); }
    S.boards = new Map(state.boards.map((b) => [b.id, b]));
    renderBoards();
    if (!S.chosen || !S.runs.has(S.selected)) S.selected = firstDetailed();
    renderAll();
    loadGrid();
    loadSamples();
  });
  es.onmessage = (e) => {
    const msg = JSON.parse(e.data);
    if (msg.type === "leaderboard") { S.boards.set(msg.board.id, msg.board); renderBoards(); return; }
    if (msg.type !== "run") return;
    const v = msg.run;
    const isNew = !S.runs.has(v.id);
    colorOf(v.id);
    S.runs.set(v.id, v);
    document.getElementById("updated").textContent = "updated " + new Date().toLocaleTimeString();
    if (isNew) {
      // runs load side by side: keep the server's order, and show the first until one is chosen
      S.runs = new Map([...S.runs.entries()].sort((a, b) => a[1].order - b[1].order));
      if (!S.chosen) { const first = firstDetailed(); if (first !== S.selected) { S.selected = first; S.grid = null; } }
      renderAll(); loadGrid(); loadSamples(); return;
    }
    renderCard(v);
    renderCharts();
    if (v.id === S.selected) {
      renderTable();
      if (msg.grid_reset) scheduleGrid(); else applyCells(v.id, msg.cells);
      if (msg.grid_reset || msg.cells.length) scheduleSamples();
      if (S.episode && S.episode.run === v.id && msg.cells.some((c) => c[0] === S.episode.task && c[1] === S.episode.r)) {
        openEpisode(S.episode.run, S.episode.task, S.episode.r, true);
      }
    }
  };
  es.onerror = () => { conn.dataset.state = "lost"; conn.textContent = "reconnecting…"; };
}

function firstDetailed() {
  for (const v of S.runs.values()) if (v.report) return v.id;
  return null;
}

// -- rendering -------------------------------------------------------------------------

function renderAll() {
  const cards = document.getElementById("cards");
  cards.replaceChildren();
  if (!S.runs.size) cards.append(el("p", { class: "muted", text: "no runs yet" }));
  for (const v of S.runs.values()) renderCard(v);
  renderCharts();
  renderSelect();
  renderTable();
}

// What a run's rates are over: all its episodes (n = tasks x runs), or, while some are
// unfinished, the finished ones only (a partial estimate, so marked, with the count).
function sizeOf(v) {
  if (!v.n) return "";
  return v.partial ? `partial: ${num(v.partial.finished)} of ${num(v.partial.total)} episodes finished` : `n = ${v.n}`;
}

function renderCard(v) {
  const p = v.progress, t = v.totals;
  const frac = p.episodes_total ? p.episodes_done / p.episodes_total : 0;
  const rateWord = p.status === "running" ? "attempts/s" : "avg attempts/s";
  const solvedRate = v.report ? v.solved_rate : null;
  const over = v.partial ? ` of ${num(v.partial.finished)} finished` : "";
  const h = v.human_time;
  const card = el("div", {
    class: "card" + (v.id === S.selected ? " selected" : ""), id: "card-" + v.id, "data-run": v.id,
    style: { "--run-color": colorOf(v.id) },
    onclick: () => { if (v.report) selectRun(v.id); },
  },
  el("h3", {}, el("span", { text: `${v.title || v.env} · ${v.label}` }),
    el("span", { class: "badge " + p.status, "data-field": "status", "data-phase": p.phase || "",
      text: (p.status === "running" && p.phase && p.phase !== "running" ? p.phase : p.status) + (p.loading ? " (loading)" : "") })),
  el("div", { class: "path", text: v.path || v.name }),
  el("div", { class: "bar" }, el("div", { style: { width: (100 * frac).toFixed(1) + "%" } })),
  el("dl", { class: "kv" },
    field("episodes", `${num(p.episodes_done)} / ${num(p.episodes_total)}`, "episodes_done", p.episodes_done),
    field("n", v.n || "–", "n", v.n || ""),
    field("attempts", num(p.attempts), "attempts", p.attempts),
    field(rateWord, p.attempts_per_s === null || p.attempts_per_s === undefined ? "–" : num(p.attempts_per_s, 1), "attempts_per_s", p.attempts_per_s),
    field("ETA", p.status === "running" ? duration(p.eta_s) : "–", "eta_s", p.eta_s),
    field("solved", `${num(t.solved)}` + (solvedRate === null || solvedRate === undefined ? "" : ` (${pct(solvedRate)}${over})`), "solved", t.solved),
    field("invalid", num(t.invalid_attempts), "invalid_attempts", t.invalid_attempts),
    field("model errors", num(t.model_errors), "model_errors", t.model_errors),
    field("retries", num(t.retries), "retries", t.retries),
    field("tokens in/out", `${num(t.input_tokens)} / ${num(t.output_tokens)}`, "input_tokens", t.input_tokens),
    field("cost", "$" + num(t.cost_usd, 4), "cost_usd", t.cost_usd),
    h ? [field("human s/decision", `${num(h.median_decision_s, 1)} (median)`, "human_median_decision_s", h.median_decision_s),
      field("human s/task", `${num(h.median_task_s, 1)} (median)`, "human_median_task_s", h.median_task_s),
      field("human time", duration(h.total_s), "human_total_s", h.total_s)] : null,
  ),
  v.partial ? el("div", { class: "note partial", "data-field": "partial", text: `Rates are a partial estimate: over the ${num(v.partial.finished)} of ${num(v.partial.total)} episodes finished so far (unfinished ones left out).` }) : null,
  v.note ? el("div", { class: "note muted", text: v.note }) : null,
  ...(v.errors || []).map((e) => el("div", { class: "error", text: e })),
  );
  const old = document.getElementById("card-" + v.id);
  if (old) old.replaceWith(card); else {
    const cards = document.getElementById("cards");
    if (cards.querySelector("p.muted")) cards.replaceChildren();
    cards.append(card);
  }
}

function field(name, text, key, value) {
  return [el("dt", { text: name }), el("dd", { "data-field": key, "data-value": value === null || value === undefined ? "" : value, text })];
}

function renderSelect() {
  const sel = document.getElementById("run-select");
  sel.replaceChildren(...[...S.runs.values()].filter((v) => v.report).map((v) =>
    el("option", { value: v.id, selected: v.id === S.selected, text: `${v.title || v.env} · ${v.label} · ${v.name}` })));
  const v = S.runs.get(S.selected);
  const groups = document.getElementById("group-select");
  groups.replaceChildren(el("option", { value: "", text: "all" }),
    ...((v && v.groups) || []).map((g) => el("option", { value: g, selected: g === S.group, text: g })));
}

function renderTable() {
  const box = document.getElementById("table");
  const v = S.runs.get(S.selected);
  if (!v || !v.table) { box.replaceChildren(); return; }
  const { header, rows, key } = v.table;
  box.replaceChildren(v.partial ? el("p", { class: "note partial", text: `Partial: the figures are over the ${num(v.partial.finished)} of ${num(v.partial.total)} episodes finished so far.` }) : "",
    el("table", { class: "report", "data-run": v.id },
    el("thead", {}, el("tr", {}, header.map((h) => el("th", { text: h })))),
    el("tbody", {}, rows.map((r) => el("tr", {}, r.map((c) => el("td", { text: c })))))),
    key ? el("p", { class: "table-key muted small", text: key }) : null);
}

// The leaderboard of each directory of runs given: the server's `deepphy leaderboard` table
// (a column group per environment setting, best of a column in bold, unfinished runs so marked).
function renderBoards() {
  const boards = [...S.boards.values()];
  document.getElementById("boards").hidden = !boards.length;
  document.getElementById("board-list").replaceChildren(...boards.map(boardNode));
}

function boardNode(b) {
  const box = el("div", { class: "board", "data-root": b.path }, el("h3", { text: b.path }));
  if (!b.board) { box.append(el("p", { class: "error", text: b.error })); return box; }
  const { columns, rows, key, notes } = b.board;
  const groups = [];  // consecutive columns of one environment setting
  for (const c of columns) {
    const last = groups[groups.length - 1];
    if (last && last.title === c.title) last.n += 1; else groups.push({ title: c.title, n: 1 });
  }
  const head = el("thead", {},
    el("tr", {}, el("th", {}), groups.map((g) => el("th", { colspan: g.n, text: g.title }))),
    el("tr", {}, el("th", { text: "setting" }), columns.map((c) => el("th", { title: c.key, text: c.header }))));
  const cell = (c, column) => el("td", {
    class: c.best ? "best" : c.unfinished ? "unfinished" : c.unranked ? "unranked" : null, "data-column": `${column.title} ${column.header}`,
    "data-mean": c.mean === null ? "" : c.mean, "data-unfinished": c.unfinished || "", "data-unranked": c.unranked ? "1" : "",
    title: c.unranked ? `not ranked: other tasks, runs or attempts (n = ${c.n}) than the rows ranked` : c.run_dir || null,
    text: c.text + (c.unranked ? "\u2020" : ""),
  });
  const body = el("tbody", {}, rows.map((r) => el("tr", { "data-model": r.model, "data-format": r.format },
    el("td", { text: `${r.model} ${r.format.toUpperCase()}` }), r.cells.map((c, j) => cell(c, columns[j])))));
  box.append(el("div", { class: "table-wrap" }, el("table", { class: "report leaderboard" }, head, body)),
    el("p", { class: "table-key muted small", text: key.replace("*: best", "bold: best") }),
    notes.map((n) => el("p", { class: "note", text: `note: ${n}` })));
  return box;
}

// -- charts (inline SVG) ---------------------------------------------------------------

// One success chart per environment (its own x axis: attempts 1..K, or decisions 1..max),
// and one stars chart per game.
function renderCharts() {
  const box = document.getElementById("charts");
  const views = [...S.runs.values()].filter((v) => v.curve);
  const charts = [];
  for (const env of new Set(views.map((v) => v.env))) {
    const series = views.filter((v) => v.env === env);
    const title = series[0].title || env;
    for (const kind of ["attempts", "decisions"]) {
      const of = series.filter((v) => v.curve.kind === kind);
      if (!of.length) continue;
      const noun = kind === "attempts" ? "attempt" : of[0].curve.noun || "decision";
      charts.push(lineChart(`${kind}-${env}`, { title: `${title}: success rate within k ${noun}s`, x: `${noun} k`, env }, of));
    }
    const starred = series.filter((v) => v.stars);
    if (starred.length) charts.push(starChart(starred, title, env));
  }
  if (!charts.length) charts.push(el("p", { class: "muted", text: "no records yet" }));
  box.replaceChildren(...charts);
}

function lineChart(kind, spec, series) {
  const W = 560, H = 300, L = 46, R = 14, T = 12, B = 40;
  const shown = series.filter((v) => !S.hidden.has(v.id));
  const xs = series.flatMap((v) => v.curve.x);
  const x0 = Math.min(...xs), x1 = Math.max(...xs);
  let top = 0;
  for (const v of shown) v.curve.mean.forEach((m, i) => { top = Math.max(top, (m || 0) + (v.curve.std[i] || 0)); });
  const ymax = [0.1, 0.2, 0.25, 0.5, 0.75, 1].find((y) => y >= top + 0.01) || 1;  // five round ticks
  const X = (x) => L + (x1 === x0 ? (W - L - R) / 2 : ((x - x0) / (x1 - x0)) * (W - L - R));
  const Y = (y) => T + (1 - y / ymax) * (H - T - B);
  const svg = el("svg", { viewBox: `0 0 ${W} ${H}`, "data-kind": kind, role: "img" });
  for (let i = 0; i <= 5; i++) {
    const y = (ymax * i) / 5;
    svg.append(el("line", { class: "gridline", x1: L, x2: W - R, y1: Y(y), y2: Y(y) }),
      el("text", { x: L - 6, y: Y(y) + 4, "text-anchor": "end", text: Math.round(100 * y) + "%" }));
  }
  // x ticks: every attempt/decision (the curves have a point at each), thinned to at most 16
  const step = Math.ceil((x1 - x0 + 1) / 16);
  for (let x = x0; x <= x1; x += step) svg.append(el("text", { x: X(x), y: H - B + 16, "text-anchor": "middle", text: x }));
  svg.append(el("line", { class: "axis", x1: L, x2: W - R, y1: Y(0), y2: Y(0) }),
    el("line", { class: "axis", x1: L, x2: L, y1: T, y2: Y(0) }),
    el("text", { x: (L + W - R) / 2, y: H - 6, "text-anchor": "middle", text: spec.x }));
  for (const v of shown) {
    const c = v.curve, color = colorOf(v.id);
    const pts = c.x.map((x, i) => [x, c.mean[i] || 0, c.std[i] || 0]);
    const band = pts.map(([x, m, s]) => `${X(x)},${Y(Math.min(ymax, m + s))}`)
      .concat(pts.slice().reverse().map(([x, m, s]) => `${X(x)},${Y(Math.max(0, m - s))}`)).join(" ");
    const g = el("g", { "data-run": v.id },
      el("polygon", { points: band, fill: color, "fill-opacity": 0.12, stroke: "none" }),
      el("polyline", { points: pts.map(([x, m]) => `${X(x)},${Y(m)}`).join(" "), fill: "none", stroke: color, "stroke-width": 2 }));
    c.x.forEach((x, i) => g.append(el("circle", {
      cx: X(x), cy: Y(c.mean[i] || 0), r: 3.5, fill: color, "data-x": x, "data-value": c.mean[i], "data-std": c.std[i],
    }, el("title", { text: `${v.label} (${v.name}): ${spec.x.split(" ")[0]} ${x}: ${pct(c.mean[i])} ± ${pct(c.std[i])}` }))));
    svg.append(g);
  }
  return el("div", { class: "chart", "data-kind": kind, "data-env": spec.env }, el("h3", { text: spec.title }), svg, legend(series));
}

function legend(series) {
  return el("div", { class: "chart-legend" }, series.map((v) => el("span", {
    class: S.hidden.has(v.id) ? "off" : "", "data-run": v.id, title: v.path, "data-n": v.n || "", "data-partial": v.partial ? "1" : "",
    onclick: () => { S.hidden.has(v.id) ? S.hidden.delete(v.id) : S.hidden.add(v.id); renderCharts(); },
  }, el("i", { style: { background: colorOf(v.id) } }), `${v.title || v.env} · ${v.label} · ${v.name} `,
    el("span", { class: v.partial ? "size partial" : "size", text: `(${sizeOf(v)})` }))));
}

// Levels won with 0, 1, 2 and 3 stars (a level can be won without a star), stacked light
// to dark, one bar per run.
const STAR_COUNTS = ["0", "1", "2", "3"];

function starChart(series, title, env) {
  const W = 560, H = 300, L = 46, R = 14, T = 22, B = 40;
  const shown = series.filter((v) => !S.hidden.has(v.id));
  const levels = shown.map((v) => STAR_COUNTS.reduce((a, k) => a + (v.stars.levels_with[k] || 0), 0));
  const step = Math.max(1, Math.ceil(Math.max(1, ...levels) / 5));
  const ymax = step * Math.ceil(Math.max(1, ...levels) / step);  // a round top: the last tick is the axis' end
  const Y = (y) => T + (1 - y / ymax) * (H - T - B);
  const bw = Math.min(70, (W - L - R) / Math.max(1, shown.length) - 16);
  const svg = el("svg", { viewBox: `0 0 ${W} ${H}`, "data-kind": "stars", role: "img" });
  for (let y = 0; y <= ymax; y += step) {
    svg.append(el("line", { class: "gridline", x1: L, x2: W - R, y1: Y(y), y2: Y(y) }),
      el("text", { x: L - 6, y: Y(y) + 4, "text-anchor": "end", text: y }));
  }
  svg.append(el("line", { class: "axis", x1: L, x2: W - R, y1: Y(0), y2: Y(0) }),
    el("line", { class: "axis", x1: L, x2: L, y1: T, y2: Y(0) }),
    el("text", { x: L, y: 11, "text-anchor": "middle", text: "levels won" }));
  shown.forEach((v, i) => {
    const x = L + 12 + i * (bw + 16);
    let base = 0;
    const g = el("g", { "data-run": v.id });
    STAR_COUNTS.forEach((k, j) => {
      const n = v.stars.levels_with[k] || 0;
      g.append(el("rect", { x, y: Y(base + n), width: bw, height: Y(base) - Y(base + n), fill: colorOf(v.id), "fill-opacity": 0.2 + 0.25 * j, "data-stars": k, "data-value": n },
        el("title", { text: `${v.label}: ${num(n, 1)} levels won with ${k} star(s) (mean over runs)` })));
      base += n;
    });
    g.append(el("text", { x: x + bw / 2, y: H - B + 16, "text-anchor": "middle", text: `${num(v.stars.mean_all, 2)} ★/level` }));
    svg.append(g);
  });
  return el("div", { class: "chart", "data-kind": "stars", "data-env": env },
    el("h3", { text: `${title}: levels won with 0, 1, 2, 3 stars (light to dark)` }), svg, legend(series));
}

// -- task grid -------------------------------------------------------------------------

function selectRun(id) {
  S.chosen = true;
  if (S.selected === id) return;
  S.selected = id; S.page = 0; S.group = ""; S.grid = null;
  for (const c of document.querySelectorAll(".card")) c.classList.toggle("selected", c.dataset.run === id);
  renderSelect(); renderTable(); loadGrid(); loadSamples();
}

function scheduleGrid() {
  clearTimeout(S.gridTimer);
  S.gridTimer = setTimeout(loadGrid, 300);
}

async function loadGrid() {
  const id = S.selected;
  if (!id) { document.getElementById("grid").replaceChildren(); return; }
  const q = new URLSearchParams({ page: S.page, group: S.group });
  const res = await fetch(`/api/runs/${id}/grid?${q}`);
  if (!res.ok || id !== S.selected) return;
  S.grid = await res.json();
  S.page = S.grid.page;
  renderGrid();
}

function renderGrid() {
  const g = S.grid, box = document.getElementById("grid");
  const [unit, K] = scale(g);
  const tiles = [];
  let group = null;
  g.tasks.forEach(([task, grp], i) => {
    if (!g.group && grp !== group) { group = grp; if (grp) tiles.push(el("h4", { text: grp })); }
    tiles.push(el("div", { class: "tile" }, el("div", { class: "tid", title: task, text: task }),
      el("div", { class: "cells" }, g.cells[i].map((c, r) => cellNode(g.run, task, r, c, g)))));
  });
  box.replaceChildren(...tiles);
  const pager = document.getElementById("pager");
  const first = g.page * g.page_size + 1, last = Math.min(g.tasks_total, (g.page + 1) * g.page_size);
  pager.replaceChildren(
    el("button", { type: "button", disabled: g.page === 0, onclick: () => { S.page--; loadGrid(); }, text: "‹" }),
    `tasks ${first}–${last} of ${g.tasks_total} · ${g.runs} run(s) each`,
    el("button", { type: "button", disabled: g.page >= g.pages - 1, onclick: () => { S.page++; loadGrid(); }, text: "›" }));
  document.getElementById("legend").replaceChildren(
    el("span", {}, el("span", { class: "cell", style: { background: solvedColor(1, K) }, text: "1" }), ` solved at ${unit} 1`),
    K > 1 ? el("span", {}, el("span", { class: "cell", style: { background: solvedColor(K, K) }, text: K }), ` … at ${unit} ${K}`) : null,
    el("span", {}, el("span", { class: "cell failed" }), " failed"),
    el("span", {}, el("span", { class: "cell progress" }), " in progress"),
    el("span", {}, el("span", { class: "cell pending" }), " not started"));
}

// What a solved cell's number and colour mean: the attempt it was solved at, or, with a
// single attempt of many decisions, the decision.
function scale(g) {
  return g.k_max === 1 && g.max_steps > 1 ? ["decision", g.max_steps] : ["attempt", g.k_max];
}

// cell = [state, attempts, solved_at, invalid, stars, steps_to_solve]
function cellNode(runId, task, r, cell, g) {
  const [state, attempts, solvedAt, invalid, stars, steps] = cell;
  const [unit, K] = scale(g);
  const at = unit === "decision" ? steps : solvedAt;
  const words = { solved: `solved at ${unit} ${at}`, failed: `failed (${attempts} attempt(s))`,
    progress: `in progress (${attempts} attempt(s) so far)`, pending: "not started" }[state];
  const node = el("button", {
    type: "button", class: `cell ${state}`, "data-run": runId, "data-task": task, "data-r": r, "data-state": state,
    "data-attempts": attempts, title: `${task} · run ${r}: ${words}${invalid ? `, ${invalid} invalid` : ""}${stars !== null ? `, ${stars}★` : ""}`,
    text: state === "solved" ? (stars !== null && K === 1 ? stars + "★" : at) : "",
    onclick: state === "pending" ? null : () => openEpisode(runId, task, r),
  });
  if (state === "solved") node.style.background = solvedColor(at, K);
  return node;
}

function applyCells(runId, cells) {
  const g = S.grid;
  if (!g || g.run !== runId || !cells.length) return;
  const row = new Map(g.tasks.map(([t], i) => [t, i]));
  for (const [task, r, ...cell] of cells) {
    const i = row.get(task);
    if (i === undefined) continue;
    g.cells[i][r] = cell;
    const old = document.querySelector(`#grid .cell[data-task="${CSS.escape(task)}"][data-r="${r}"]`);
    if (old) old.replaceWith(cellNode(runId, task, r, cell, g));
  }
}

// -- the episode browser: a filterable, searchable list of the selected run's episodes ----

// sample = [task, group, run, state, attempts, solved_at, decisions, invalid, reason, stars, seconds, tokens, words]
const SAMPLE = { task: 0, group: 1, run: 2, state: 3, attempts: 4, solvedAt: 5, decisions: 6, invalid: 7, reason: 8,
  stars: 9, seconds: 10, tokens: 11, words: 12 };
const SAMPLES_SHOWN = 100;  // rows at first; "show more" adds as many
Object.assign(S, { samples: null, filtered: [], limit: SAMPLES_SHOWN, samplesTimer: null });

function scheduleSamples() {
  clearTimeout(S.samplesTimer);
  S.samplesTimer = setTimeout(loadSamples, 800);
}

async function loadSamples() {
  const id = S.selected;
  if (!id) { S.samples = null; renderSamples(); return; }
  const res = await fetch(`/api/runs/${id}/samples`);
  if (!res.ok || id !== S.selected) return;
  const fresh = !S.samples || S.samples.run !== id;
  S.samples = await res.json();
  if (fresh) { S.limit = SAMPLES_SHOWN; renderFilters(); }
  renderSamples();
}

function option(value, text, selected) {
  return el("option", { value, text, selected: value === selected });
}

function renderFilters() {
  const rows = S.samples ? S.samples.rows : [];
  const reasons = new Map();
  for (const r of rows) if (r[SAMPLE.reason]) reasons.set(r[SAMPLE.reason], (reasons.get(r[SAMPLE.reason]) || 0) + 1);
  const keep = (id) => document.getElementById(id).value;
  const reason = keep("f-reason"), group = keep("f-group"), attempts = keep("f-attempts");
  document.getElementById("f-reason").replaceChildren(option("", "any", reason), option("*", "any invalid attempt", reason),
    ...[...reasons].sort((a, b) => b[1] - a[1]).map(([k, n]) => option(k, `${k} (${n})`, reason)));
  const groups = [...new Set(rows.map((r) => r[SAMPLE.group]).filter(Boolean))];
  document.getElementById("f-group").replaceChildren(option("", "all", group), ...groups.map((g) => option(g, g, group)));
  const K = S.samples ? S.samples.k_max : 1;
  document.getElementById("f-attempts").replaceChildren(option("", "any", attempts),
    ...Array.from({ length: K }, (_, i) => option(String(i + 1), String(i + 1), attempts)));
}

function filterSamples() {
  if (!S.samples) return [];
  const outcome = document.getElementById("f-outcome").value, reason = document.getElementById("f-reason").value;
  const group = document.getElementById("f-group").value, attempts = document.getElementById("f-attempts").value;
  const words = document.getElementById("f-search").value.trim().toLowerCase().split(/\s+/).filter(Boolean);
  return S.samples.rows.filter((r) => (!outcome || r[SAMPLE.state] === outcome)
    && (!reason || (reason === "*" ? r[SAMPLE.invalid] > 0 : r[SAMPLE.reason] === reason))
    && (!group || r[SAMPLE.group] === group) && (!attempts || r[SAMPLE.attempts] === Number(attempts))
    && words.every((w) => `${r[SAMPLE.task]} ${r[SAMPLE.group]} ${r[SAMPLE.reason] || ""} ${r[SAMPLE.words]}`.toLowerCase().includes(w)));
}

function renderSamples() {
  const table = document.getElementById("samples");
  const more = document.getElementById("samples-more");
  S.filtered = filterSamples();
  if (!S.samples) { table.replaceChildren(); more.hidden = true; document.getElementById("f-count").textContent = ""; return; }
  const who = S.samples.human ? "human s" : "model s";
  const words = { solved: "solved", failed: "failed", progress: "in progress" };
  table.replaceChildren(
    el("thead", {}, el("tr", {}, ["task", "group", "run", "outcome", "attempts", "decisions", "invalid", "stars", who, "tokens"]
      .map((h) => el("th", { text: h, title: h === who ? (S.samples.human ? "the person's time to decide, all attempts" : "the model's time to answer, all attempts") : null })))),
    el("tbody", {}, S.filtered.slice(0, S.limit).map((r) => el("tr", {
      class: "sample", tabindex: 0, "data-task": r[SAMPLE.task], "data-r": r[SAMPLE.run], "data-state": r[SAMPLE.state],
      onclick: () => openEpisode(S.samples.run, r[SAMPLE.task], r[SAMPLE.run]),
      onkeydown: (e) => { if (e.key === "Enter") openEpisode(S.samples.run, r[SAMPLE.task], r[SAMPLE.run]); },
    },
    el("td", { text: r[SAMPLE.task] }), el("td", { text: r[SAMPLE.group] }), el("td", { text: r[SAMPLE.run] }),
    el("td", {}, el("span", { class: r[SAMPLE.state] === "solved" ? "ok" : r[SAMPLE.state] === "failed" ? "bad" : "muted",
      text: words[r[SAMPLE.state]] + (r[SAMPLE.state] === "solved" && r[SAMPLE.solvedAt] ? ` at ${r[SAMPLE.solvedAt]}` : "") })),
    el("td", { text: r[SAMPLE.attempts] }), el("td", { text: r[SAMPLE.decisions] }),
    el("td", { class: "reason", title: r[SAMPLE.reason] || null, text: r[SAMPLE.invalid] ? `${r[SAMPLE.invalid]}: ${r[SAMPLE.reason]}` : "" }),
    el("td", { text: r[SAMPLE.stars] === null ? "" : `${r[SAMPLE.stars]}★` }),
    el("td", { text: num(r[SAMPLE.seconds], 1) }), el("td", { text: num(r[SAMPLE.tokens]) })))));
  more.hidden = S.filtered.length <= S.limit;
  document.getElementById("f-count").textContent = `${num(S.filtered.length)} of ${num(S.samples.rows.length)} episodes`;
}

// -- one episode (with ‹ › through the list, another run beside it, images enlarged on a click)

// Where the open episode is in the filtered list: [index, length] (index -1: not in it).
function placeInList() {
  const e = S.episode;
  if (!e || !S.samples || S.samples.run !== e.run) return [-1, 0];
  return [S.filtered.findIndex((r) => r[SAMPLE.task] === e.task && r[SAMPLE.run] === e.r), S.filtered.length];
}

function moveInList(by) {
  const [i, n] = placeInList();
  if (!n) return;
  const j = i < 0 ? 0 : i + by;
  if (j < 0 || j >= n) return;
  const r = S.filtered[j];
  openEpisode(S.samples.run, r[SAMPLE.task], r[SAMPLE.run]);
}

function renderPlace() {
  const [i, n] = placeInList();
  document.getElementById("episode-place").textContent = n ? (i < 0 ? `not in the list (${n})` : `${i + 1} of ${n}`) : "";
  document.getElementById("episode-prev").disabled = !n || i === 0;
  document.getElementById("episode-next").disabled = !n || i === n - 1;
}

// What can go beside an episode: its other runs (repetitions), and the same task in the other runs of its environment.
function renderCompare(ep) {
  const select = document.getElementById("episode-compare");
  const chosen = S.episode.compare || "";
  const here = S.runs.get(ep.run_id);
  const options = [option("", "nothing", chosen)];
  for (let r = 0; r < (here ? here.runs : 1); r++) if (r !== ep.run) options.push(option(`${ep.run_id}|${r}`, `run ${r} of this`, chosen));
  for (const v of S.runs.values()) {
    if (v.id === ep.run_id || v.env !== ep.env || !v.report) continue;
    for (let r = 0; r < v.runs; r++) options.push(option(`${v.id}|${r}`, `${v.label} · ${v.name} · run ${r}`, chosen));
  }
  select.replaceChildren(...options);
}

async function fetchEpisode(runId, task, r) {
  const res = await fetch(`/api/runs/${runId}/episode?` + new URLSearchParams({ task, run: r }));
  if (!res.ok) throw new Error(await res.text());
  return res.json();
}

async function openEpisode(runId, task, r, refresh = false) {
  const modal = document.getElementById("episode");
  const compare = refresh && S.episode ? S.episode.compare : "";
  S.episode = { run: runId, task, r, compare };
  renderPlace();
  if (!refresh) {
    document.getElementById("episode-title").textContent = `${task} · run ${r}`;
    document.getElementById("episode-body").replaceChildren(el("p", { class: "muted", text: "loading…" }));
    modal.hidden = false;
    history.replaceState(null, "", `#run=${runId}&task=${encodeURIComponent(task)}&r=${r}`);
  }
  let ep, other = null;
  try {
    ep = await fetchEpisode(runId, task, r);
    if (compare) { const [cid, cr] = compare.split("|"); other = await fetchEpisode(cid, task, Number(cr)).catch((e) => ({ error: String(e.message || e) })); }
  } catch (e) {
    document.getElementById("episode-body").replaceChildren(el("p", { class: "error", text: String(e.message || e) }));
    return;
  }
  if (!S.episode || S.episode.task !== task || S.episode.r !== r || S.episode.run !== runId) return;
  document.getElementById("episode-title").textContent =
    `${ep.task} · run ${ep.run} · ${ep.env} · ${ep.label}` + (ep.group ? ` · ${ep.group}` : "");
  renderCompare(ep);
  const open = new Set([...document.querySelectorAll("#episode-body .side:first-child details.attempt[open]")].map((d) => d.dataset.attempt));
  const main = episodeNode(ep, refresh ? open : null);
  document.getElementById("episode-body").replaceChildren(other
    ? el("div", { class: "compare-grid" }, el("div", { class: "side", "data-run": ep.run_id }, main),
      el("div", { class: "side", "data-run": compare.split("|")[0] }, other.error ? el("p", { class: "error", text: other.error }) : episodeNode(other, null)))
    : el("div", { class: "side", "data-run": ep.run_id }, main));
}

function episodeNode(ep, open) {
  const [state, attempts, solvedAt] = ep.cell;
  const v = S.runs.get(ep.run_id);
  const human = Boolean(v && v.human);
  return [
    sideTitle(ep),
    el("p", {}, state === "solved" ? el("span", { class: "ok", text: `solved at attempt ${solvedAt}` })
      : state === "failed" ? el("span", { class: "bad", text: `failed after ${attempts} attempt(s)` })
      : el("span", { text: `${attempts} attempt(s) so far, not finished` }), ` · K = ${ep.k_max}, at most ${ep.max_steps} decision(s) per attempt`),
    timelineNode(ep, human),
    el("p", { class: "muted small", text: "Images: every image of every prompt (the current observation and the history) and the key frames are files of the run directory; click one to see it at full size. Runs made before deepphy stored prompt images kept only key frames, and an image they did not keep is marked so." }),
    ep.attempts.map((a, i) => attemptNode(ep, a, open ? open.has(String(a.attempt)) : i === ep.attempts.length - 1, human)),
  ];
}

function sideTitle(ep) {
  return el("h3", { class: "side-title", text: `${ep.label} · run ${ep.run}` });
}

// Every decision of the episode on one line per attempt, as wide as the time it took to decide
// (a person's time, or the model's answer), with the attempt's tokens.
function timelineNode(ep, human) {
  const all = ep.attempts.flatMap((a) => a.timing.decision_s || []);
  const most = Math.max(1e-9, ...all);
  return el("div", { class: "timeline", "data-kind": human ? "human" : "model" },
    el("div", { class: "field", text: `decisions: ${human ? "the person's time to decide" : "the model's time to answer"} (bar length), tokens per attempt` }),
    ep.attempts.map((a) => {
      const u = a.model_stats.usage;
      const times = a.timing.decision_s || [];
      return el("div", { class: "tl-row", "data-attempt": a.attempt },
        el("span", { class: "tl-label" }, `attempt ${a.attempt} `, a.success ? el("span", { class: "ok", text: "✓" }) : a.invalid_reason ? el("span", { class: "bad", text: "invalid" }) : el("span", { class: "bad", text: "✗" })),
        el("span", { class: "tl-bars" }, a.steps.map((st, i) => el("span", {
          class: "tl-bar" + (st.invalid_reason ? " invalid" : ""), "data-step": st.step, "data-seconds": times[i] ?? "",
          style: { width: `${Math.max(6, 100 * (times[i] || 0) / most).toFixed(1)}%` },
          title: `decision ${st.step}: ${times[i] === undefined ? "no time recorded" : times[i].toFixed(2) + " s"} · ${st.action_text || st.invalid_reason || ""}`,
        }, `${st.step}: ${times[i] === undefined ? "–" : times[i].toFixed(1) + " s"}`))),
        el("span", { class: "tl-tokens muted small", text: `${num(u.input_tokens)} / ${num(u.output_tokens)} tokens` }));
    }));
}

// Key frames belong to the decision their file name carries (r<run>_a<attempt>_s<step>_...).
function framesOf(a, step) {
  return a.key_frames.filter((f) => f.path.split("/").pop().includes(`_a${a.attempt}_s${step}_`));
}

function attemptNode(ep, a, isOpen, human) {
  const tied = new Set(a.steps.flatMap((s) => framesOf(a, s.step)).map((f) => f.path));
  const loose = a.key_frames.filter((f) => !tied.has(f.path));
  const status = a.success ? el("span", { class: "ok", text: "solved" })
    : a.invalid_reason ? el("span", { class: "bad", text: "invalid" }) : el("span", { class: "bad", text: "failed" });
  const u = a.model_stats.usage;
  return el("details", { class: "attempt", open: isOpen, "data-attempt": a.attempt },
    el("summary", {}, `Attempt ${a.attempt}`, status, a.stars !== null ? `${a.stars}★` : null,
      el("span", { class: "outcome", text: a.feedback }),
      el("a", { class: "replay", target: "_blank", text: "▶ replay", title: "the attempt simulated again, as an animation",
        href: "/replay?" + new URLSearchParams({ run: ep.run_id, task: ep.task, r: ep.run, a: a.attempt }) })),
    el("div", { class: "attempt-body" },
      el("div", { class: "field", text: `${a.steps.length} decision(s) · env ${a.timing.env_s.toFixed(2)} s · ${human ? "human time to decide" : "model"} ${a.timing.model_s.toFixed(2)} s · tokens ${u.input_tokens}/${u.output_tokens} · $${u.cost_usd.toFixed(4)}` + (a.model_stats.retries ? ` · ${a.model_stats.retries} retries` : "") + (a.model_stats.model_errors ? ` · ${a.model_stats.model_errors} model errors` : "") }),
      a.steps.map((s) => stepNode(ep, a, s)),
      loose.length ? [el("div", { class: "field", text: "key frames" }), el("div", { class: "imgs" }, loose.map((f) => figure(ep.run_id, f.path, f.caption)))] : null));
}

function stepNode(ep, a, s) {
  const frames = framesOf(a, s.step);
  const prompt = ep.prompts[s.prompt];
  const standIn = s.step > 1 ? framesOf(a, s.step - 1)[0] : null;
  return el("div", { class: "step", "data-step": s.step },
    el("h4", { text: `Decision ${s.step}` }),
    el("div", { class: "prompt" },
      el("div", { class: "field", text: "prompt" }),
      prompt ? prompt.map((m) => messageNode(ep, m, standIn)) : el("p", { class: "error", text: `prompt ${s.prompt} is missing from the run directory` })),
    el("div", {},
      el("div", { class: "field", text: "raw reply" }), el("pre", { class: "reply", text: s.raw_output }),
      s.prediction !== null ? [el("div", { class: "field", text: "prediction (WM)" }), el("pre", { class: "prediction", text: s.prediction })] : null,
      s.action !== null ? [el("div", { class: "field", text: "parsed action" }), el("pre", { class: "action", text: s.action_text || JSON.stringify(s.action) })]
        : [el("div", { class: "field", text: "invalid" }), el("pre", { class: "invalid bad", text: s.invalid_reason || "" })],
      s.action !== null && s.invalid_reason ? el("pre", { class: "invalid bad", text: s.invalid_reason }) : null,
      s.feedback ? [el("div", { class: "field", text: "outcome" }), el("pre", { text: s.feedback })] : null,
      Object.keys(s.info || {}).length ? el("details", {}, el("summary", { class: "field", text: "info" }), el("pre", { text: JSON.stringify(s.info, null, 1) })) : null,
      frames.length ? [el("div", { class: "field", text: "key frames" }), el("div", { class: "imgs" }, frames.map((f) => figure(ep.run_id, f.path, f.caption)))] : null));
}

function messageNode(ep, m, standIn) {
  const parts = [];
  let current = false;
  for (const p of m.content) {
    if (p.type === "text") {
      if (p.text === "Current observation:") current = true;
      parts.push(el("pre", { text: p.text }));
    } else if (p.file) {
      parts.push(figure(ep.run_id, p.file, p.caption));
    } else {
      parts.push(el("div", { class: "imgs" }, el("div", { class: "missing", "data-missing": p.name },
        `image "${p.name}" (${current ? "current observation" : "earlier observation"}) — ${p.problem || "not stored in the run directory"}`),
        current && standIn ? figure(ep.run_id, standIn.path, `closest stored image: the key frame after the previous decision (${standIn.caption}), not the image the model saw`) : null));
    }
  }
  return el("details", { open: m.role !== "system" }, el("summary", { text: `${m.role} message` }), parts);
}

function figure(runId, path, caption) {
  const url = `/files/${runId}/` + path.split("/").map(encodeURIComponent).join("/");
  return el("figure", {}, el("img", { src: url, alt: caption, title: "click to see it at full size", class: "zoomable",
    onclick: () => enlarge(url, caption) }), el("figcaption", { text: caption }));  // eager: a screenshot or print shows them
}

function enlarge(url, caption) {
  const box = document.getElementById("lightbox");
  box.querySelector("img").src = url;
  box.querySelector(".caption").textContent = caption;
  box.hidden = false;
}

function closeEpisode() {
  document.getElementById("episode").hidden = true;
  S.episode = null;
  history.replaceState(null, "", location.pathname);
}

// -- wiring ----------------------------------------------------------------------------

document.getElementById("episode-close").addEventListener("click", closeEpisode);
document.getElementById("episode").addEventListener("click", (e) => { if (e.target.id === "episode") closeEpisode(); });
document.getElementById("episode-prev").addEventListener("click", () => moveInList(-1));
document.getElementById("episode-next").addEventListener("click", () => moveInList(1));
document.getElementById("episode-compare").addEventListener("change", (e) => {
  if (!S.episode) return;
  S.episode.compare = e.target.value;
  openEpisode(S.episode.run, S.episode.task, S.episode.r, true);
});
document.getElementById("lightbox").addEventListener("click", () => { document.getElementById("lightbox").hidden = true; });
document.addEventListener("keydown", (e) => {
  const lightbox = document.getElementById("lightbox");
  if (e.key === "Escape" && !lightbox.hidden) { lightbox.hidden = true; return; }
  if (!S.episode || e.target.matches("input, select, textarea")) return;
  if (e.key === "Escape") closeEpisode();
  else if (e.key === "ArrowLeft") moveInList(-1);
  else if (e.key === "ArrowRight") moveInList(1);
});
document.getElementById("run-select").addEventListener("change", (e) => selectRun(e.target.value));
document.getElementById("group-select").addEventListener("change", (e) => { S.group = e.target.value; S.page = 0; loadGrid(); });
for (const id of ["f-outcome", "f-reason", "f-group", "f-attempts"]) {
  document.getElementById(id).addEventListener("change", () => { S.limit = SAMPLES_SHOWN; renderSamples(); renderPlace(); });
}
document.getElementById("f-search").addEventListener("input", () => { S.limit = SAMPLES_SHOWN; renderSamples(); renderPlace(); });
document.getElementById("samples-more").addEventListener("click", () => { S.limit += SAMPLES_SHOWN; renderSamples(); });

const hash = new URLSearchParams(location.hash.slice(1));
if (hash.get("run")) {
  S.selected = hash.get("run");
  S.chosen = true;
  if (hash.get("task")) openEpisode(hash.get("run"), hash.get("task"), Number(hash.get("r") || 0));
}
connect();
