// drivestudio studio: the page. One WebSocket to the server that served it; frames come as binary messages
// (a JSON header with the step's state, then JPEG images), everything else as JSON text (docs/studio.md).
"use strict";

const $ = (id) => document.getElementById(id);

// What the page measured, for people (the status line) and for tests and the benchmark (window.studio).
const studio = window.studio = {
  hello: null, role: null, state: null, frames: 0, drawn: 0, bytes: 0,
  latencies: [], errors: [], infos: [], drawTimes: [], connected: false, closed: null, closeReason: "",
  behindSeen: [],
};

let ws = null;
let keys = { left: false, right: false, up: false, down: false };
let pad = null;                 // the gamepad's axes, or null
let pendingPress = null;        // a key press whose effect on the command is awaited
let pendingDriver = null;       // the driver chosen in the menu until the server drives with it or refuses it
let lastPadSent = "";
let behindUntil = 0;            // the "behind real time" note stays this long after the last step behind

const BEHIND_HOLD_MS = 3000;    // a note that flickers for one frame is no note: it stays for 3 s
// the input a key moves: index in state.input (steer, throttle, brake) and the direction it moves it
const KEY_INPUT = { left: [0, -1], right: [0, 1], up: [1, 1], down: [2, 1] };

const KEYMAP = { ArrowLeft: "left", a: "left", A: "left", ArrowRight: "right", d: "right", D: "right",
                 ArrowUp: "up", w: "up", W: "up", ArrowDown: "down", s: "down", S: "down" };

function send(obj) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj));
}

function message(kind, text) {
  const list = kind === "error" ? studio.errors : studio.infos;
  list.push(text);
  const div = document.createElement("div");
  div.className = kind;
  div.textContent = (kind === "error" ? "error: " : "") + text;
  const box = $("messages");
  box.prepend(div);
  while (box.children.length > 6) box.lastChild.remove();
}

// --- connection ------------------------------------------------------------------------------------------------
function connect() {
  const scheme = location.protocol === "https:" ? "wss://" : "ws://";
  ws = new WebSocket(scheme + location.host + "/ws");
  ws.binaryType = "arraybuffer";
  ws.onopen = () => { studio.connected = true; };
  ws.onclose = (e) => {
    studio.connected = false;
    studio.closed = e.code;
    studio.closeReason = e.reason || "";
    const world = studio.hello ? `${studio.hello.world}: ` : "";
    // the server says why when it stops (the run ended, the studio stopped); without a reason the page was
    // refused or the connection lost
    $("world").textContent = world + (e.reason ? `${e.reason}; the last frame stays shown`
      : studio.hello ? "disconnected: the connection to the studio was lost (reload to try again)"
        : "not connected: the studio refused this page or is not running (reload to try again)");
    $("role").textContent = "disconnected";
    $("role").className = "badge";
    $("claim").hidden = true;
    $("behind").hidden = true;
    status();
    setControls(false);
  };
  ws.onmessage = (e) => {
    if (typeof e.data === "string") onText(JSON.parse(e.data));
    else onFrame(e.data);
  };
}

function onText(msg) {
  if (msg.type === "hello") onHello(msg);
  else if (msg.type === "role") setRole(msg.role, msg.wheel_free);
  else if (msg.type === "error") {
    message("error", msg.message);
    if (msg.about === "driver") {       // refused: the menu names who drives
      pendingDriver = null;
      if (studio.state) $("driver").value = studio.state.driver;
    }
  }
  else if (msg.type === "info") message("info", msg.message);
}

function onHello(h) {
  studio.hello = h;
  $("world").textContent = `${h.world}: ${h.title}` + (h.studio ? "" : " (watching a running job)");
  for (const el of document.querySelectorAll(".studio-only")) el.hidden = !h.studio;
  $("help-watch").hidden = h.studio;
  if (!h.studio && h.controls) $("help-watch").textContent += " Space pauses or resumes it, N steps it once.";
  $("run-controls").hidden = !h.studio && !h.controls;
  fill($("driver"), h.drivers);
  fill($("mode"), h.modes);
  fill($("operation"), ["(default)"].concat(h.operations));
  $("mode-label").hidden = !h.modes.length;
  $("operation-label").hidden = !h.operations.length;
  $("scene-key").textContent = h.scene_key;
  $("labels-note").textContent = h.labels_note || "";
  fill($("scene"), ["(as started)"].concat(h.scenes));
  const cams = $("cameras");
  cams.innerHTML = "";
  const row = document.createElement("div");
  row.style.display = "flex";
  row.style.gap = "6px";
  for (const name of h.cameras) {
    const c = document.createElement("canvas");
    c.id = "cam-" + name;
    c.title = name;
    row.appendChild(c);
  }
  cams.appendChild(row);
  setRole(h.role, h.wheel_free);
}

function fill(select, options) {
  select.innerHTML = "";
  for (const o of options) {
    const opt = document.createElement("option");
    opt.value = o.startsWith("(") ? "" : o;
    opt.textContent = o;
    select.appendChild(opt);
  }
}

function setRole(role, wheelFree) {
  studio.role = role;
  const badge = $("role");
  badge.textContent = role === "driver" ? "you hold the wheel" : "watching";
  badge.className = "badge " + role;
  $("claim").hidden = !(role !== "driver" && wheelFree);
  setControls(role === "driver");
}

function setControls(on) {
  for (const el of document.querySelectorAll("#bar button, #bar select, #bar input")) el.disabled = !on;
}

// --- frames ----------------------------------------------------------------------------------------------------
async function onFrame(buffer) {
  studio.frames += 1;
  studio.bytes += buffer.byteLength;
  const view = new DataView(buffer);
  const n = view.getUint32(0);
  const state = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, n)));
  onState(state);
  let at = 4 + n;
  const draws = [];
  for (const img of state.images) {
    const blob = new Blob([new Uint8Array(buffer, at, img.bytes)], { type: "image/jpeg" });
    at += img.bytes;
    const canvas = img.name === "topdown" ? $("topdown") : $("cam-" + img.name);
    if (canvas) draws.push(createImageBitmap(blob).then((bmp) => draw(canvas, bmp)));
  }
  try { await Promise.all(draws); } catch (err) { message("error", "a frame could not be decoded: " + err); }
  studio.drawn += 1;
  const now = performance.now();
  studio.drawTimes.push(now);
  while (studio.drawTimes.length && now - studio.drawTimes[0] > 1000) studio.drawTimes.shift();
  send({ type: "ack", seq: state.seq });
}

function draw(canvas, bmp) {
  if (canvas.width !== bmp.width || canvas.height !== bmp.height) {
    canvas.width = bmp.width;
    canvas.height = bmp.height;
    const scale = canvas.id === "topdown" ? 1 : (bmp.width < 300 ? 2 : 1.5);
    canvas.style.width = bmp.width * scale + "px";
    canvas.style.height = bmp.height * scale + "px";
  }
  canvas.getContext("2d").drawImage(bmp, 0, 0);
  bmp.close();
}

function onState(s) {
  const before = studio.state;
  studio.state = s;
  if (s.paused) pendingPress = null;         // a paused run changes no command: nothing to time
  if (pendingPress && JSON.stringify(s.command) !== pendingPress.command) {
    studio.latencies.push(performance.now() - pendingPress.t0);
    pendingPress = null;
  }
  document.body.classList.toggle("paused", !!s.paused);
  document.body.classList.toggle("takeover", !!s.takeover);
  if (pendingDriver === s.driver) pendingDriver = null;
  if (pendingDriver === null && (!before || $("driver").value !== s.driver)) $("driver").value = s.driver;
  renderLive(s);
  renderLabels(s.labels);
  renderCommand(s);
  renderPairs($("controller"), s.controller);
  renderPairs($("metrics"), Object.assign({ "t [s]": s.t.toFixed(1), "loop [Hz]": s.loop_hz.toFixed(0),
                                            "speed [m/s]": s.speed }, s.metrics || {}));
  const rec = $("record");
  rec.classList.toggle("on", !!s.recording);
  rec.textContent = s.recording ? `■ Stop (${s.recording.steps} steps, ${s.recording.shards} shards)` : "● Record";
  $("realtime").checked = !!s.realtime;
}

// the speed now, off the road, and a loop that falls behind real time
function renderLive(s) {
  $("speed").textContent = s.speed === null || s.speed === undefined ? "-"
    : `${s.speed.toFixed(1)} m/s  ${(s.speed * 3.6).toFixed(0)} km/h`;
  $("offroad").hidden = !s.off_road;
  $("offroad").textContent = studio.hello && studio.hello.scene_key === "path" ? "off the path" : "off road";
  const now = performance.now();
  if (s.behind !== null && s.behind !== undefined) {
    studio.behindSeen.push(s.behind);
    behindUntil = now + BEHIND_HOLD_MS;
    const hold = studio.hello && studio.hello.takeover_hold;
    const el = $("behind");
    el.textContent = `behind real time: ${s.behind.toFixed(2)} simulated s per s` +
      (hold ? ` (a take-over lasts ${(hold / Math.max(s.behind, 0.01)).toFixed(1)} s)` : "");
    el.title = "the loop cannot keep up with real time (a busy CPU, a slow driver): the world, the ramps of " +
               "the keys and a take-over run in simulated time, so they take longer on the wall clock";
  }
  $("behind").hidden = !s.realtime || !!s.paused || now > behindUntil;
}

function fmt(v) {
  if (v === null || v === undefined) return "-";
  if (typeof v === "number") {
    if (Number.isInteger(v)) return String(v);
    const text = Math.abs(v) >= 100 ? v.toFixed(1) : v.toFixed(3);
    return /^-0\.0+$/.test(text) ? text.slice(1) : text;
  }
  return String(v);
}

// Liu and Wang's Figure 13: every label's truth against the estimate, with an error bar (full at its scale)
function renderLabels(labels) {
  const t = $("labels");
  if (t.rows.length !== labels.length + 1) {
    t.innerHTML = "<tr><td>label</td><td class=num>truth</td><td class=num>estimate</td>" +
                  "<td class=num>|error|</td><td></td></tr>";
    for (const l of labels) {
      const r = t.insertRow();
      r.innerHTML = `<td>${l.name}</td><td class=num></td><td class=num></td><td class=num></td>` +
                    `<td><div class="bar"><div></div></div></td>`;
      r.title = `${l.name} [${l.unit}]; the bar is full at an error of ${l.scale}`;
    }
  }
  labels.forEach((l, i) => {
    const c = t.rows[i + 1].cells;
    c[1].textContent = fmt(l.truth);
    c[2].textContent = fmt(l.estimate);
    const bar = c[4].firstChild.firstChild;
    if (l.truth === null || l.estimate === null) { c[3].textContent = "-"; bar.style.width = "0"; return; }
    const err = Math.abs(l.estimate - l.truth);
    const frac = Math.min(1, err / l.scale);
    c[3].textContent = fmt(err);
    bar.style.width = (frac * 100).toFixed(1) + "%";
    bar.className = frac < 0.25 ? "ok" : frac < 0.75 ? "warn" : "bad";
  });
}

function renderCommand(s) {
  const h = studio.hello;
  const t = $("command");
  if (t.rows.length !== h.action.length) {
    t.innerHTML = "";
    for (const a of h.action) {
      const r = t.insertRow();
      r.innerHTML = `<td>${a.name}</td><td class=num></td><td><div class="bar"><div class="centre"></div></div></td>`;
    }
  }
  h.action.forEach((a, i) => {
    const v = s.command[i];
    const c = t.rows[i].cells;
    c[1].textContent = fmt(v);
    const span = a.high - a.low;
    const from = (Math.min(v, a.neutral) - a.low) / span, to = (Math.max(v, a.neutral) - a.low) / span;
    const bar = c[2].firstChild.firstChild;
    bar.style.left = (from * 100).toFixed(1) + "%";
    bar.style.width = (Math.max(0.01, to - from) * 100).toFixed(1) + "%";
  });
  $("who").textContent = `${s.driver}` + (s.takeover ? " - taken over by the human" : "") +
                         (s.paused ? " - paused" : "");
}

function renderPairs(table, obj) {
  const entries = Object.entries(obj || {});
  if (table.rows.length !== entries.length) {
    table.innerHTML = "";
    for (let i = 0; i < entries.length; i++) table.insertRow().innerHTML = "<td></td><td class=num></td>";
  }
  entries.forEach(([k, v], i) => {
    table.rows[i].cells[0].textContent = k;
    table.rows[i].cells[1].textContent = fmt(v);
  });
}

// --- the person at the controls ------------------------------------------------------------------------------
function typing(e) {
  const tag = (e.target && e.target.tagName) || "";
  return tag === "INPUT" || tag === "SELECT" || tag === "TEXTAREA";
}

function sendInput() {
  send({ type: "input", keys: keys, gamepad: pad });
}

// whether pressing key k changes the command: not while paused, not under a gamepad (its axes rule), not when
// the input it moves is already at its end (the throttle full: up changes nothing)
function moves(k) {
  const s = studio.state;
  if (!s || s.paused || !s.input) return false;
  if (pad && Math.max(Math.abs(pad.steer), pad.throttle, pad.brake) > 0.08) return false;
  const [i, dir] = KEY_INPUT[k];
  return dir > 0 ? s.input[i] < 1 : s.input[i] > -1;
}

document.addEventListener("keydown", (e) => {
  if (typing(e) || studio.role !== "driver") return;
  const k = KEYMAP[e.key];
  if (k) {
    e.preventDefault();
    if (!keys[k]) {
      keys = Object.assign({}, keys, { [k]: true });
      if (!pendingPress && moves(k)) {
        pendingPress = { t0: performance.now(), key: k, command: JSON.stringify(studio.state.command) };
      }
      sendInput();
    }
  } else if (e.key === " ") {
    e.preventDefault();
    send({ type: studio.state && studio.state.paused ? "resume" : "pause" });
  } else if (e.key === "n" || e.key === "N") {
    send({ type: "step" });
  }
});

document.addEventListener("keyup", (e) => {
  const k = KEYMAP[e.key];
  if (k && keys[k]) {
    keys = Object.assign({}, keys, { [k]: false });
    if (pendingPress && pendingPress.key === k) pendingPress = null;   // let go before any step took it
    sendInput();
  }
});

window.addEventListener("blur", () => {   // a key held while the window loses focus is released
  if (Object.values(keys).some((v) => v)) {
    keys = { left: false, right: false, up: false, down: false };
    sendInput();
  }
});

// the Gamepad API: the first pad in the standard mapping; polled every animation frame
function pollGamepad() {
  const pads = navigator.getGamepads ? navigator.getGamepads() : [];
  const gp = Array.from(pads).find((p) => p);
  let next = null;
  if (gp) {
    const trig = (i) => (gp.buttons[i] ? gp.buttons[i].value : 0);
    let throttle = trig(7), brake = trig(6);
    if (throttle < 0.05 && brake < 0.05 && gp.axes.length > 1) {   // no triggers: the left stick's Y
      throttle = Math.max(0, -gp.axes[1]);
      brake = Math.max(0, gp.axes[1]);
    }
    const r = (v) => Math.round(Math.max(-1, Math.min(1, v)) * 100) / 100;
    next = { steer: r(gp.axes[0] || 0), throttle: r(throttle), brake: r(brake) };
  }
  const text = JSON.stringify(next);
  if (text !== lastPadSent && studio.role === "driver") {
    pad = next;
    lastPadSent = text;
    sendInput();
  }
  requestAnimationFrame(pollGamepad);
}

// --- the bar's controls ----------------------------------------------------------------------------------------
function wire() {
  // a control keeps no focus once used, so that the arrows and Space drive the car and not a list or a button
  for (const kind of ["change", "click"]) {
    document.addEventListener(kind, (e) => {
      const tag = e.target && e.target.tagName;
      if (tag === "SELECT" || tag === "BUTTON" || (tag === "INPUT" && e.target.type === "checkbox")) e.target.blur();
    });
  }
  $("pause").onclick = () => send({ type: "pause" });
  $("resume").onclick = () => send({ type: "resume" });
  $("step").onclick = () => send({ type: "step" });
  $("realtime").onchange = (e) => send({ type: "pace", realtime: e.target.checked });
  $("driver").onchange = (e) => {
    pendingDriver = e.target.value;
    send({ type: "driver", name: e.target.value });
  };
  $("mode").onchange = (e) => send({ type: "mode", mode: e.target.value });
  $("operation").onchange = (e) => { if (e.target.value) send({ type: "operation", operation: e.target.value }); };
  $("claim").onclick = () => send({ type: "claim" });
  $("reset").onclick = () => {
    const h = studio.hello;
    const msg = { type: "reset", seed: Math.max(0, parseInt($("seed").value || "0", 10)) };
    const scene = $("procedural").value.trim() || $("scene").value;
    if (scene) msg[h.scene_key] = scene;
    send(msg);
  };
  $("record").onclick = () => {
    if (studio.state && studio.state.recording) send({ type: "record", on: false });
    else {
      const name = $("rec-name").value.trim();
      send(name ? { type: "record", on: true, name: name } : { type: "record", on: true });
    }
  };
  setInterval(status, 500);
}

// the status line: the page's frame rate, the loop rate and the last key-to-command latency, while connected
function status() {
  const s = studio.state;
  const lat = studio.latencies;
  const last = lat.length ? ` | key to command ${lat[lat.length - 1].toFixed(0)} ms` : "";
  if (!studio.connected) $("status").textContent = studio.closed === null ? "" : "disconnected";
  else $("status").textContent = s ? `page ${studio.drawTimes.length} frames/s | loop ${s.loop_hz.toFixed(0)} Hz${last}`
                                   : "";
}

wire();
connect();
requestAnimationFrame(pollGamepad);
