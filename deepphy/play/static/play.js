"use strict";
// The play page: the prompt a model would get (rules, history, the current observation),
// controls that write the action, and what each decision did. The server pushes its whole
// state over Server-Sent Events whenever it changes; a page closed and opened again finds
// the same decision waiting.

const $ = (s) => document.querySelector(s);
let state = null;
let shownKey = null; // the decision on screen
let checkTimer = null;
let checked = { text: null, ok: false };

function setConn(s) {
  const c = $("#conn");
  c.dataset.state = s;
  c.textContent = { live: "live", lost: "reconnecting…", connecting: "connecting…" }[s];
}

function connect() {
  const source = new EventSource("/api/events");
  source.addEventListener("state", (e) => { setConn("live"); render(JSON.parse(e.data)); });
  source.onerror = () => setConn("lost");
}

function render(s) {
  state = s;
  $("#title").textContent = `· ${s.title}`;
  $("#player").textContent = `player ${s.player}`;
  const p = s.progress;
  const per = p.seconds_per_decision === null ? "" : ` · ${p.seconds_per_decision.toFixed(1)} s per decision`;
  $("#progress").textContent = `${p.episodes_done} of ${p.episodes_total} task(s) done · ${p.solved} solved · ${p.attempts} attempt(s)${per}`;
  document.title = `deepphy play · ${s.title}`;
  renderStatus(s);
  renderLast(s);
  renderDecision(s);
  renderRecent(s);
}

function renderStatus(s) {
  const status = $("#status");
  status.hidden = Boolean(s.decision) && !s.busy;
  status.textContent = s.error ? `Error: ${s.error}`
    : s.finished ? `All ${s.progress.episodes_total} task(s) are done: thank you! The run is in ${s.run_dir}.`
    : s.busy ? "The world is running…"
    : s.decision ? "" : s.progress.attempts || s.last ? "Preparing the next decision…"
    : `Loading ${s.title} (a simulator can take some seconds to start)…`;
  status.dataset.state = s.finished ? "finished" : s.busy ? "busy" : s.decision ? "deciding" : "waiting";
}

function replayLink(s, task, run, attempt, words) {
  const q = new URLSearchParams({ run: s.run_id, task, r: run, a: attempt });
  return el("a", { href: `/replay?${q}`, target: "_blank", class: "replay", text: words });
}

function nounOf(s) {
  return s.step_noun === "step" ? "decision" : s.step_noun;
}

// The latest decision: the person's own action; what it did comes with the next prompt, as
// it comes to a model. Once the task's episode is over: its name, outcome and replay.
function renderLast(s) {
  const box = $("#last");
  const last = s.last;
  box.hidden = !last;
  if (!last) return;
  const record = last.record;
  const id = `${last.id}:${Boolean(last.attempt_over)}:${Boolean(record)}`;
  if (box.dataset.id === id) return;
  box.dataset.id = id;
  const where = `task ${last.episode}, attempt ${last.attempt}`;
  const head = last.text !== null && last.text !== undefined
    ? el("p", { class: "outcome" }, last.step ? `Your ${nounOf(s)} ${last.step} (${where}): ` : `Your action (${where}): `, el("code", { text: last.text }))
    : null;
  const next = !record ? el("p", { class: "muted small", text: last.attempt_over
    ? `Attempt ${last.attempt} ended without solving the task; the prompt below shows it as the model is shown it.`
    : "What it did is in the prompt below, as the model is shown it." }) : null;
  const over = record ? el("p", { class: "outcome", "data-outcome": record.success ? "solved" : "failed" },
    el("span", { class: record.success ? "ok" : "bad", text: record.success ? "Solved" : "Not solved" }),
    record.stars !== null && record.stars !== undefined ? ` with ${record.stars} star(s)` : "",
    ` · task ${last.episode} was ${last.task} (run ${last.run}), attempt ${last.attempt}. `,
    replayLink(s, last.task, last.run, last.attempt, "watch the replay")) : null;
  const outcome = record && record.outcome ? el("p", { class: "muted small", text: record.outcome }) : null;
  box.replaceChildren(...[head, next, over, outcome].filter(Boolean));
}

// A part of the prompt, as the model gets it: a text, or an image (no caption: a model gets none).
function part(p) {
  if (p.text !== undefined) {
    return p.text.includes("\n") ? el("pre", { text: p.text, "data-part": p.part }) : el("p", { text: p.text, "data-part": p.part });
  }
  return el("img", { class: "prompt-image", src: p.image, alt: p.caption, width: p.width, height: p.height, "data-part": p.part, title: "click to enlarge", onclick: (e) => e.target.classList.toggle("big") });
}

function renderDecision(s) {
  const d = s.decision;
  const box = $("#decision");
  box.hidden = !d;
  if (!d) { shownKey = null; return; }
  const submit = $("#submit");
  if (d.key === shownKey) { submit.disabled = s.busy || !checked.ok; return; }
  shownKey = d.key;
  box.dataset.key = d.key;
  // The task by its place, not its name (a name can hint at the solution; the model is not told it)
  $("#where").textContent = `Task ${d.episode} of ${s.progress.episodes_total} · attempt ${d.attempt} of ${s.max_attempts}` + (s.max_steps > 1 ? ` · ${nounOf(s)} ${d.step}` : "");
  $("#system").textContent = d.system;
  $("#rules").open = d.step === 1 && d.attempt === 1;
  $("#history").hidden = d.before.length === 0;
  $("#before").replaceChildren(...d.before.map(part));

  // the observation: captions and text as the model reads them, images with an overlay for the controls
  const stages = {};
  const texts = [];
  const obs = d.observation.map((p) => {
    if (p.text !== undefined) { if (p.part !== d.observation[0].part) texts.push(p.text); return part(p); }
    const img = el("img", { src: p.image, alt: p.caption, width: p.width, height: p.height, "data-image": p.name, "data-part": p.part });
    const canvas = el("canvas", { "data-image": p.name });
    const stage = el("div", { class: "stage" }, img, canvas);
    stages[p.name] = { stage, img, canvas };
    return stage;
  });
  $("#observation").replaceChildren(...obs);

  const input = $("#action");
  input.value = "";
  checked = { text: null, ok: false };
  $("#check").textContent = "";
  submit.disabled = true;
  const make = CONTROLS[d.space.kind];
  const controls = make ? make({ space: d.space, stages, text: texts.join("\n"), set: setAction })
    : el("p", { class: "hint", text: "No controls for this kind of action: type the action in the syntax the rules give." });
  $("#controls").replaceChildren(controls);
  tick();
}

function setAction(text) {
  $("#action").value = text;
  scheduleCheck();
}

function scheduleCheck() {
  clearTimeout(checkTimer);
  $("#submit").disabled = true;
  checkTimer = setTimeout(check, 120);
}

async function post(url, body) {
  const response = await fetch(url, { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
  return response;
}

async function check() {
  const text = $("#action").value;
  const out = $("#check");
  if (!state || !state.decision) return;
  if (!text.trim()) { out.textContent = ""; checked = { text, ok: false }; return; }
  const response = await post("/api/check", { key: state.decision.key, text });
  const result = await response.json();
  if (text !== $("#action").value) return; // a newer text is being checked
  checked = { text, ok: result.ok };
  out.className = `check ${result.ok ? "ok" : "bad"}`;
  out.textContent = result.ok ? `✓ ${result.action}` : `✗ ${result.error}`;
  out.dataset.ok = result.ok ? "1" : "0";
  $("#submit").disabled = !result.ok || state.busy;
}

async function act() {
  const text = $("#action").value;
  if (!state || !state.decision || !checked.ok || checked.text !== text) return;
  $("#submit").disabled = true;
  const response = await post("/api/answer", { key: state.decision.key, text });
  if (!response.ok) {
    $("#check").className = "check bad";
    $("#check").textContent = `✗ ${await response.text()}`;
  }
}

function tick() {
  const clock = $("#clock");
  if (state && state.decision) {
    const s = Math.max(0, Date.now() / 1000 - state.decision.asked_at);
    clock.textContent = `${Math.floor(s / 60)}:${String(Math.floor(s % 60)).padStart(2, "0")}`;
  }
}

function renderRecent(s) {
  const box = $("#recent");
  box.hidden = s.recent.length === 0;
  const rows = s.recent.map((a) => el("tr", { "data-episode": a.episode, "data-attempt": a.attempt, "data-over": a.over ? "1" : "0" },
    el("td", { text: a.over ? a.task : `task ${a.episode} (in play)` }), el("td", { text: `run ${a.run}` }), el("td", { text: `attempt ${a.attempt}` }),
    el("td", {}, a.over ? el("span", { class: a.success ? "ok" : "bad", text: a.success ? "solved" : a.invalid ? "invalid" : "not solved" }) : el("span", { class: "bad", text: "not solved" }),
      a.over && a.stars !== null && a.stars !== undefined ? ` ${a.stars}★` : ""),
    el("td", { text: `${a.decisions} decision(s)` }),
    el("td", {}, a.over ? replayLink(s, a.task, a.run, a.attempt, "replay") : el("span", { class: "muted small", text: "replay once the task is over" }))));
  $("#recent-table").replaceChildren(...rows);
}

$("#action").addEventListener("input", scheduleCheck);
$("#action").addEventListener("keydown", (e) => { if (e.key === "Enter") act(); });
$("#submit").addEventListener("click", act);
setInterval(tick, 1000);
connect();
