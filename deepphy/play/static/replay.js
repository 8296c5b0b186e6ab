"use strict";
// A recorded attempt, simulated again and shown as an animation of the world: the pictures
// come from the server (`/api/runs/<run>/replay`), FILM_FPS per simulated second.
// (el() comes from controls.js.)

const q = new URLSearchParams(location.search);
let film = null, frame = 0, playing = true, timer = null;
const $ = (s) => document.querySelector(s);

async function load() {
  const api = `/api/runs/${encodeURIComponent(q.get("run"))}/replay?` +
    new URLSearchParams({ task: q.get("task"), run: q.get("r"), attempt: q.get("a") });
  const response = await fetch(api);
  if (!response.ok) { $("#status").textContent = `No replay: ${await response.text()}`; return; }
  film = await response.json();
  $("#what").textContent = `${film.env} · ${film.task} · run ${film.run} · attempt ${film.attempt} · ${film.model}`;
  $("#outcome").replaceChildren(el("span", { class: film.success ? "ok" : "bad", text: film.success ? "Solved" : "Not solved" }),
    film.stars !== null ? ` with ${film.stars} star(s)` : "", `: ${film.outcome.replace(/^(solved|failed)\.\s*/, "")}`);
  $("#note").textContent = film.note || (film.matches ? `Simulated again from the recorded actions; every decision's result equals the record.` : "");
  $("#note").className = film.matches ? "hint" : "bad";
  $("#decisions").replaceChildren(...film.decisions.map((d) => el("li", {},
    el("a", { href: "#", onclick: (e) => { e.preventDefault(); show(d.picture); } }, d.action ? el("code", { text: d.action }) : el("span", { class: "bad", text: `invalid: ${d.invalid_reason}` })),
    d.feedback ? ` → ${d.feedback}` : "")));
  for (const p of film.pictures) new Image().src = p.url; // fetch them all now: playback without gaps
  $("#scrub").max = film.pictures.length - 1;
  $("#status").hidden = true;
  $("#player").hidden = false;
  $("#player").dataset.pictures = film.pictures.length;
  show(0);
  schedule();
}

function show(i) {
  frame = Math.max(0, Math.min(film.pictures.length - 1, i));
  const p = film.pictures[frame];
  $("#picture").src = p.url;
  $("#caption").textContent = p.caption;
  $("#scrub").value = frame;
  $("#count").textContent = `${frame + 1} / ${film.pictures.length}`;
  $("#player").dataset.frame = frame;
}

function schedule() {
  clearTimeout(timer);
  if (!playing) return;
  const speed = Number($("#speed").value);
  const delay = (film.filmed ? 1000 / film.fps : 1200) / speed;
  timer = setTimeout(() => {
    if (frame < film.pictures.length - 1) { show(frame + 1); schedule(); }
    else { playing = false; $("#play").textContent = "play again"; }
  }, delay);
}

$("#play").addEventListener("click", () => {
  if (!playing && frame >= film.pictures.length - 1) show(0);
  playing = !playing;
  $("#play").textContent = playing ? "pause" : "play";
  schedule();
});
$("#scrub").addEventListener("input", (e) => { playing = false; $("#play").textContent = "play"; show(Number(e.target.value)); });
$("#speed").addEventListener("change", schedule);
load();
