"use strict";
// Controls made for a person, one per kind of action space (the space's JSON travels with
// every decision). Each writes the environment's own action syntax with `set(text)`; the
// server parses it with the environment's parser before the person can act, so a control
// that drifts from the syntax shows the parser's reason instead of acting.
//
// A control is CONTROLS[kind]({space, stages, text, set}) -> element, where `stages` maps
// the observation's image names to {img, canvas} (a canvas laid over the image, in the
// image's own pixels) and `text` is the observation's text state.

const CONTROLS = {};

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined) node.append(c);
  return node;
}

function svg(tag, attrs = {}, ...children) {
  const node = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const c of children.flat()) if (c) node.append(c);
  return node;
}

function section(label, ...children) {
  return el("div", { class: "ctl" }, el("div", { class: "ctl-label", text: label }), ...children);
}

// Buttons of which one (or, with `many`, several) is on; `onpick(value)` on a click.
function choices(name, options, onpick) {
  const box = el("div", { "data-control": name });
  const buttons = options.map(([value, label]) => el("button", {
    type: "button", "data-value": String(value), text: label, onclick: () => onpick(value) }));
  box.append(...buttons);
  box.mark = (isOn) => buttons.forEach((b, i) => b.classList.toggle("on", isOn(options[i][0])));
  return box;
}

// Where a pointer event falls on a stage, as fractions of the image (0..1 right and down).
function fraction(event, canvas) {
  const box = canvas.getBoundingClientRect();
  return [(event.clientX - box.left) / box.width, (event.clientY - box.top) / box.height];
}

// Run `draw(ctx, w, h)` on a stage's canvas once its image has a size (now, or when loaded).
function painter(stage, draw) {
  const paint = () => {
    const { img, canvas } = stage;
    if (!img.naturalWidth) return;
    canvas.width = img.naturalWidth;
    canvas.height = img.naturalHeight;
    const ctx = canvas.getContext("2d");
    ctx.clearRect(0, 0, canvas.width, canvas.height);
    draw(ctx, canvas.width, canvas.height);
  };
  stage.img.addEventListener("load", paint);
  return paint;
}

// Python's f"{x:.{d}f}" with trailing zeros (and a bare point) dropped: how the spaces write numbers.
function decimal(x, d) {
  return Number(x).toFixed(d).replace(/0+$/, "").replace(/\.$/, "");
}

function pickStage(stages, preferred) {
  for (const name of preferred) if (stages[name]) return stages[name];
  return Object.values(stages)[0];
}

// -- PHYRE: click a cell of the numbered grid, choose a radius ---------------------------------

const PHYRE_SCENE = 256; // px of PHYRE's scene (the image shows it at any size)

CONTROLS.phyre_grid = ({ space, stages, set }) => {
  const stage = pickStage(stages, ["grid"]);
  const n = space.grid;
  let cell = null, level = null;
  const radiusPx = (l) => space.radius_levels === 1 ? space.r_max
    : space.r_min + (space.r_max - space.r_min) * (l - 1) / (space.radius_levels - 1);
  const paint = painter(stage, (ctx, w, h) => {
    if (cell === null) return;
    const row = Math.floor((cell - 1) / n), col = (cell - 1) % n;
    ctx.strokeStyle = "#f59e0b"; ctx.lineWidth = Math.max(2, w / 200);
    ctx.strokeRect(col * w / n, row * h / n, w / n, h / n);
    if (level !== null) {
      ctx.fillStyle = "rgba(243, 79, 70, 0.75)";
      ctx.beginPath();
      ctx.arc((col + 0.5) * w / n, (row + 0.5) * h / n, radiusPx(level) * w / PHYRE_SCENE, 0, 2 * Math.PI);
      ctx.fill();
    }
  });
  const radii = choices("radius", Array.from({ length: space.radius_levels }, (_, i) =>
    [i + 1, `${i + 1} (${decimal(radiusPx(i + 1), 1)} px)`]), (l) => { level = l; update(); });
  const shown = el("div", { class: "hint", "data-control": "cell-shown" });
  function update() {
    radii.mark((l) => l === level);
    shown.textContent = cell === null ? "Click a cell of the grid image." : `Cell ${cell}`;
    paint();
    set(cell !== null && level !== null ? `Cell: ${cell}, Radius: ${level}` : "");
  }
  stage.stage.classList.add("active");
  stage.canvas.addEventListener("click", (e) => {
    const [fx, fy] = fraction(e, stage.canvas);
    const col = Math.min(n - 1, Math.floor(fx * n)), row = Math.min(n - 1, Math.floor(fy * n));
    cell = row * n + col + 1;
    update();
  });
  update();
  return el("div", {}, el("p", { class: "hint", text: "The red ball's centre goes to the centre of the cell you click; the radius sets its size." }),
    section("cell", shown), section("radius", radii));
};

CONTROLS.phyre_continuous = ({ stages, set }) => {
  const stage = pickStage(stages, ["axes"]);
  let x = null, y = null, r = 0.5;
  const paint = painter(stage, (ctx, w, h) => {
    if (x === null) return;
    ctx.fillStyle = "rgba(243, 79, 70, 0.75)";
    ctx.beginPath();
    ctx.arc(x * w, (1 - y) * h, (r * 30 + 2) / PHYRE_SCENE * w, 0, 2 * Math.PI);
    ctx.fill();
  });
  const slider = el("input", { type: "range", min: 0, max: 1, step: 0.01, value: r, "data-control": "r",
    oninput: (e) => { r = Number(e.target.value); update(); } });
  const shown = el("div", { class: "hint" });
  function update() {
    shown.textContent = x === null ? "Click where the ball's centre goes." : `X ${x}, Y ${y} (from the bottom)`;
    paint();
    set(x === null ? "" : `X: ${x}, Y: ${y}, R: ${decimal(r, 3)}`);
  }
  stage.stage.classList.add("active");
  stage.canvas.addEventListener("click", (e) => {
    const [fx, fy] = fraction(e, stage.canvas);
    x = Number(decimal(Math.min(1, Math.max(0, fx)), 3));
    y = Number(decimal(Math.min(1, Math.max(0, 1 - fy)), 3));
    update();
  });
  update();
  return el("div", {}, section("position", shown), section("radius R (0..1)", slider));
};

// -- I-PHYRE: a timeline per gray block; click it where the block should go -----------------

const IPHYRE_TIME = 15; // s simulated per attempt: a removal happens at 0 <= t < 15

CONTROLS.iphyre_plan = ({ space, set }) => {
  const times = new Array(space.num_blocks).fill(null);
  let chosen = false; // no plan until the person makes one: an empty plan is a whole attempt too
  const lanes = el("div", { class: "lanes" });
  const rows = [];
  for (let i = 0; i < space.num_blocks; i++) {
    const mark = el("div", { class: "mark", hidden: true });
    const lane = el("div", { class: "lane", "data-control": "lane", "data-index": i, title: "click: remove the block at that time" },
      ...[3, 6, 9, 12].map((t) => el("div", { class: "tick", style: `left:${100 * t / IPHYRE_TIME}%` })), mark);
    const input = el("input", { type: "number", min: 0, max: IPHYRE_TIME - 0.1, step: 0.1, placeholder: "s",
      "data-control": "time", "data-index": i, oninput: (e) => {
        times[i] = e.target.value === "" ? null : Math.min(IPHYRE_TIME - 0.1, Math.max(0, Number(e.target.value)));
        chosen = true;
        update(false);
      } });
    lane.addEventListener("click", (e) => {
      const [fx] = fraction(e, lane);
      times[i] = Math.min(IPHYRE_TIME - 0.1, Math.max(0, Math.round(fx * IPHYRE_TIME * 10) / 10));
      chosen = true;
      update(true);
    });
    const clear = el("button", { type: "button", text: "×", title: "keep this block", onclick: () => { times[i] = null; chosen = true; update(true); } });
    rows.push({ mark, input });
    lanes.append(el("span", { text: `block ${i}` }), lane, input, clear);
  }
  const axis = el("div", { class: "lane-axis" }, ...[0, 3, 6, 9, 12, 15].map((t) => el("span", { text: `${t} s` })));
  function update(writeInputs) {
    rows.forEach(({ mark, input }, i) => {
      mark.hidden = times[i] === null;
      if (times[i] !== null) mark.style.left = `${100 * times[i] / IPHYRE_TIME}%`;
      if (writeInputs) input.value = times[i] === null ? "" : times[i].toFixed(1);
    });
    const plan = times.map((t, i) => [t, i]).filter(([t]) => t !== null).sort((a, b) => a[0] - b[0] || a[1] - b[1]);
    none.classList.toggle("on", chosen && plan.length === 0);
    if (!chosen) return set("");
    // json.dumps of the plan, as the space writes it (floats with a point)
    set("[" + plan.map(([t, i]) => `{"time": ${Number.isInteger(t) ? t.toFixed(1) : String(t)}, "index": ${i}}`).join(", ") + "]");
  }
  const none = el("button", { type: "button", "data-control": "no-removal", text: "remove nothing",
    title: "an attempt in which no block is removed", onclick: () => { times.fill(null); chosen = true; update(true); } });
  update(true);
  return el("div", {}, el("p", { class: "hint", text: "Each gray block (numbered on the annotated image) has a timeline: click it at the moment the block should disappear, or type the time. Blocks without a time stay." }),
    section("removals", lanes, el("div", { class: "lanes" }, el("span"), axis, el("span"), el("span"))), section("or", none));
};

// -- Kinetix: every motor and thruster, for the next stretch of time ------------------------

CONTROLS.kinetix_vector = ({ space, set }) => {
  const values = new Array(space.num_motors + space.num_thrusters).fill(0);
  let chosen = false; // nothing is sent until the person sets something (all off is a decision too)
  const boxes = [];
  const box = el("div");
  for (let i = 0; i < values.length; i++) {
    const motor = i < space.num_motors;
    const label = motor ? `M${i}` : `T${i - space.num_motors}`;
    const options = motor ? [[0, "off"], [1, "forward"], [2, "reverse"]] : [[0, "off"], [1, "on"]];
    const c = choices(label, options, (v) => { values[i] = v; chosen = true; update(); });
    boxes.push(c);
    box.append(section(`${label} (${motor ? "motor" : "thruster"})`, c));
  }
  function update() {
    boxes.forEach((c, i) => c.mark((v) => chosen && v === values[i]));
    run.classList.toggle("on", chosen);
    set(chosen ? `[${values.join(", ")}]` : "");
  }
  const run = el("button", { type: "button", "data-control": "as-set", text: values.length ? "as set (the rest off)" : "let it run",
    onclick: () => { chosen = true; update(); } });
  update();
  const none = values.length === 0 ? el("p", { class: "hint", text: "This level has nothing to control: choose \"let it run\", then act." }) : null;
  return el("div", {}, el("p", { class: "hint", text: "Set every motor and thruster (labelled M and T on the annotated image); they hold these settings until your next decision. Those you do not set are off." }), none, box, section("or", run));
};

// -- Pooltool: speed, and where the cue strikes the cue ball --------------------------------

const POOL_ROWS = ["top", "middle", "bottom"], POOL_COLS = ["left", "centre", "right"];

CONTROLS.pooltool_shot = ({ set }) => {
  let speed = null, spot = null;
  const speeds = choices("speed", [["Low", "Low"], ["Medium", "Medium"], ["High", "High"]], (v) => { speed = v; update(); });
  const dots = [];
  const ball = svg("svg", { class: "cueball", width: 150, height: 150, viewBox: "-75 -75 150 150", "data-control": "spot" },
    svg("circle", { cx: 0, cy: 0, r: 70, fill: "#fafaf5", stroke: "#333", "stroke-width": 2 }));
  POOL_ROWS.forEach((row, r) => POOL_COLS.forEach((col, c) => {
    const name = `${row}-${col}`;
    // corner spots sit nearer the centre, as on the space (0.35 on both axes vs 0.5 on one)
    const k = r !== 1 && c !== 1 ? 0.7 : 1;
    const dot = svg("circle", { class: "spot", cx: (c - 1) * 40 * k, cy: (r - 1) * 40 * k, r: 9, "data-value": name,
      fill: "#cbd5e1", stroke: "#475569", onclick: () => { spot = name; update(); } },
      svg("title", {}, name));
    dots.push([name, dot]);
    ball.append(dot);
  }));
  const shown = el("div", { class: "hint" });
  function update() {
    speeds.mark((v) => v === speed);
    dots.forEach(([name, dot]) => dot.setAttribute("fill", name === spot ? "#f59e0b" : "#cbd5e1"));
    shown.textContent = spot ? `strike spot: ${spot}` : "Click where the cue strikes the cue ball (as the shooter sees it).";
    set(speed && spot ? `Speed: ${speed}, Strikespot: ${spot}` : "");
  }
  update();
  return el("div", {}, el("p", { class: "hint", text: "The cue aims at the lowest-numbered ball by itself (the dashed line). Top spots follow through, bottom spots draw back, left and right add side spin." }),
    section("speed", speeds), section("strike spot", ball, shown));
};

// -- Angry Birds: the launch angle and power; drag on the dial or set the numbers -----------

CONTROLS.angrybirds_shoot = ({ set }) => {
  let angle = null, power = null; // no shot until the person sets both
  const R = 120;
  const arrow = svg("line", { x1: 10, y1: 140, stroke: "#d64545", "stroke-width": 4, "stroke-linecap": "round" });
  const dial = svg("svg", { class: "dial", width: 150, height: 150, viewBox: "0 0 150 150", "data-control": "dial" },
    svg("path", { d: `M10 140 L${10 + R} 140 A${R} ${R} 0 0 0 10 ${140 - R} Z`, fill: "#eef2ff", stroke: "#c7d2fe" }),
    svg("path", { d: `M10 140 L${10 + R * 0.5} 140 A${R * 0.5} ${R * 0.5} 0 0 0 10 ${140 - R * 0.5} Z`, fill: "none", stroke: "#dbe2fb" }),
    arrow);
  const angleIn = el("input", { type: "number", min: 0, max: 90, step: 0.01, "data-control": "angle" });
  const powerIn = el("input", { type: "number", min: 0, max: 1, step: 0.01, "data-control": "power" });
  const angleRange = el("input", { type: "range", min: 0, max: 90, step: 0.01 });
  const powerRange = el("input", { type: "range", min: 0, max: 1, step: 0.01 });
  const bound = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  angleIn.addEventListener("input", () => { if (angleIn.value !== "") { angle = bound(Number(angleIn.value), 0, 90); update(angleIn); } });
  powerIn.addEventListener("input", () => { if (powerIn.value !== "") { power = bound(Number(powerIn.value), 0, 1); update(powerIn); } });
  angleRange.addEventListener("input", () => { angle = Number(angleRange.value); update(angleRange); });
  powerRange.addEventListener("input", () => { power = Number(powerRange.value); update(powerRange); });
  const drag = (e) => {
    if (e.type !== "pointerdown" && !(e.buttons & 1)) return;
    const box = dial.getBoundingClientRect();
    const dx = (e.clientX - box.left) * 150 / box.width - 10, dy = 140 - (e.clientY - box.top) * 150 / box.height;
    angle = Math.round(bound(Math.atan2(dy, dx) * 180 / Math.PI, 0, 90) * 100) / 100;
    power = Math.round(bound(Math.hypot(dx, dy) / R, 0, 1) * 100) / 100;
    update(null);
  };
  dial.addEventListener("pointerdown", drag);
  dial.addEventListener("pointermove", drag);
  function update(source) {
    for (const [input, v] of [[angleIn, angle], [powerIn, power], [angleRange, angle], [powerRange, power]]) {
      if (input !== source && v !== null) input.value = decimal(v, 2);
    }
    arrow.setAttribute("visibility", angle === null || power === null ? "hidden" : "visible");
    if (angle === null || power === null) return set("");
    const a = angle * Math.PI / 180;
    arrow.setAttribute("x2", 10 + Math.cos(a) * R * power);
    arrow.setAttribute("y2", 140 - Math.sin(a) * R * power);
    set(`shoot(angle=${decimal(angle, 2)}, power=${decimal(power, 2)})`);
  }
  update(null);
  return el("div", {}, el("p", { class: "hint", text: "Angle in degrees above the horizontal (0 flat to the right, 90 straight up); power from 0 to 1 of the full pull. Drag on the dial or set the numbers." }),
    dial, section("angle (degrees)", angleRange, " ", angleIn), section("power (0..1)", powerRange, " ", powerIn));
};

// -- Cut the Rope: click a labelled element (on the buttons or the scene), several ropes at once, or wait

const ROPE_ACTIONS = { P: "cut_pin", A: "cut_active_pin" };

CONTROLS.cuttherope = ({ space, stages, text, set }) => {
  let current = null; // {name, ids: [...]} | {name: "tap_air_cushion", id} | {name: "sleep"} | {name: "success"|"fail"}
  let times = 1, seconds = "1";
  const buttons = []; // [letter, id, button]
  const elementButton = (letter, id) => {
    const b = el("button", { type: "button", text: `${letter}${id}`, "data-element": `${letter}${id}`, onclick: () => pick(letter, id) });
    buttons.push([letter, id, b]);
    return b;
  };
  function pick(letter, id) {
    if (ROPE_ACTIONS[letter]) {
      const name = ROPE_ACTIONS[letter];
      if (current && current.name === name) {
        const ids = current.ids.includes(id) ? current.ids.filter((x) => x !== id) : [...current.ids, id];
        current = ids.length ? { name, ids } : null;
      } else current = { name, ids: [id] };
    } else if (letter === "B") current = { name: "pop_bubble", ids: [id] };
    else if (letter === "C") current = { name: "tap_air_cushion", ids: [id] };
    update();
  }
  const range = (n) => Array.from({ length: n }, (_, i) => i + 1);
  const parts = [];
  if (space.pins.length) parts.push(section("cut the rope of a pin (several: cut at the same moment)", space.pins.map((i) => elementButton("P", i))));
  if (space.active_pins.length) parts.push(section("cut (or remove) an active pin", space.active_pins.map((i) => elementButton("A", i))));
  if (space.bubbles.length) parts.push(section("pop a bubble", space.bubbles.map((i) => elementButton("B", i))));
  if (space.num_cushions) {
    const taps = choices("times", [[1, "1 puff"], [3, "3 puffs"], [5, "5 puffs"]], (v) => { times = v; update(); });
    parts.push(section("tap an air cushion", range(space.num_cushions).map((i) => elementButton("C", i)), taps));
    parts.taps = taps;
  }
  const secondsIn = el("input", { type: "number", min: 0.1, max: 10, step: 0.1, value: seconds, "data-control": "seconds",
    oninput: (e) => { seconds = e.target.value; if (current && current.name === "sleep") update(); } });
  const wait = el("button", { type: "button", text: "wait", "data-control": "wait", onclick: () => { current = { name: "sleep" }; update(); } });
  const claim = el("button", { type: "button", text: "success()", "data-control": "success", title: "declare the level won: the world runs on to decide", onclick: () => { current = { name: "success" }; update(); } });
  const give = el("button", { type: "button", text: "fail()", "data-control": "fail", title: "stop acting", onclick: () => { current = { name: "fail" }; update(); } });
  parts.push(section("let the world run", wait, " ", secondsIn, " s"), section("end", claim, give));

  // The scene: a click picks the nearest labelled element the text state places there.
  const stage = pickStage(stages, ["scene"]);
  const places = [];
  const label = /\b([PABC])(\d+) (?:at )?\((-?\d+(?:\.\d+)?), (-?\d+(?:\.\d+)?)\)/g;
  for (const m of text.matchAll(label)) {
    const [letter, id] = [m[1], Number(m[2])];
    if (buttons.some(([l, i]) => l === letter && i === id)) places.push([letter, id, Number(m[3]), Number(m[4])]);
  }
  const paint = painter(stage, (ctx, w) => {
    if (!current || !current.ids) return;
    ctx.strokeStyle = "#f59e0b"; ctx.lineWidth = Math.max(3, w / 160);
    for (const [letter, id, x, y] of places) {
      const on = current.ids.includes(id) && (ROPE_ACTIONS[letter] === current.name || (letter === "B" && current.name === "pop_bubble")
        || (letter === "C" && current.name === "tap_air_cushion"));
      if (on) { ctx.beginPath(); ctx.arc(x, y, 22, 0, 2 * Math.PI); ctx.stroke(); }
    }
  });
  if (places.length) {
    stage.stage.classList.add("active");
    stage.canvas.addEventListener("click", (e) => {
      const [fx, fy] = fraction(e, stage.canvas);
      const x = fx * stage.img.naturalWidth, y = fy * stage.img.naturalHeight;
      let best = null, bestD = 40;
      for (const p of places) {
        const d = Math.hypot(p[2] - x, p[3] - y);
        if (d < bestD) { best = p; bestD = d; }
      }
      if (best) pick(best[0], best[1]);
    });
  }

  function update() {
    for (const [letter, id, b] of buttons) {
      const name = ROPE_ACTIONS[letter] || (letter === "B" ? "pop_bubble" : "tap_air_cushion");
      b.classList.toggle("on", Boolean(current && current.name === name && current.ids.includes(id)));
    }
    if (parts.taps) parts.taps.mark((v) => v === times);
    wait.classList.toggle("on", Boolean(current && current.name === "sleep"));
    claim.classList.toggle("on", Boolean(current && current.name === "success"));
    give.classList.toggle("on", Boolean(current && current.name === "fail"));
    paint();
    if (!current) return set("");
    if (current.name === "sleep") return set(`sleep(${decimal(Number(seconds), 2)})`);
    if (current.name === "success" || current.name === "fail") return set(`${current.name}()`);
    if (current.name === "tap_air_cushion") return set(`tap_air_cushion(${current.ids[0]}, times=${times})`);
    return set(`${current.name}(${[...current.ids].sort((a, b) => a - b).join(", ")})`);
  }
  update();
  return el("div", {}, el("p", { class: "hint", text: "Click a labelled element on the scene or its button below. Pick several ropes to cut them at the same moment." }), ...parts);
};
