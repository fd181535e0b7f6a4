// The digiteyes 3D mouse page (thesis Fig. 4.9): a ground plane, the mouse pole with its
// shadow, and a sphere that the thumb button picks up and puts down. States arrive over a
// WebSocket (digiteyes/apps/mouse_server.py); the scene is drawn with canvas 2D through a
// pinhole camera written here. Units: table millimetres, z up.
"use strict";

const LIGHT = [0.35, -0.25, 1.0];    // direction towards the light (shadows fall away from it)
const EYE = [280.0, -480.0, 330.0];  // viewer position, mm
const TARGET = [0.0, 15.0, 25.0];    // point looked at, mm
const FOCAL_PX = 900.0;
const GRID_HALF_MM = 120.0;
const GRID_STEP_MM = 20.0;

// Everything the page knows, exposed for tests and the console.
const mouse = {
  connected: false, ended: false, error: null, description: "",
  pole: null,                 // [x, y, height] mm, as received
  buttons: {},                // name -> pressed
  sphere: { centre: [0, 30, 15], radius: 15, held: false, offset: [0, 0, 0] },
  reachMm: 45,
  frames: [],                 // per frame: index, pole, buttons, sphere centre, held, latency
  latencyMs: null,
  lost: false,
  imageFrames: 0,
};
window.digiteyesMouse = mouse;

function sub(a, b) { return [a[0] - b[0], a[1] - b[1], a[2] - b[2]]; }
function add(a, b) { return [a[0] + b[0], a[1] + b[1], a[2] + b[2]]; }
function dot(a, b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
function cross(a, b) {
  return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
}
function unit(a) { const n = Math.hypot(a[0], a[1], a[2]); return [a[0] / n, a[1] / n, a[2] / n]; }

// Camera axes (x right, y down, z forward) of a look-at camera with world z up.
const AXIS_Z = unit(sub(TARGET, EYE));
const AXIS_X = unit(cross(AXIS_Z, [0, 0, 1]));
const AXIS_Y = cross(AXIS_Z, AXIS_X);

function project(canvas, p) {
  const d = sub(p, EYE);
  const z = dot(d, AXIS_Z);
  return { x: canvas.width / 2 + FOCAL_PX * dot(d, AXIS_X) / z,
           y: canvas.height / 2 + FOCAL_PX * dot(d, AXIS_Y) / z, depth: z };
}

// Where a point falls on the ground (z = 0) along the light direction.
function shadowOf(p) {
  const l = unit(LIGHT);
  const s = p[2] / l[2];
  return [p[0] - s * l[0], p[1] - s * l[1], 0.0];
}

function poleTip() { return mouse.pole ? [mouse.pole[0], mouse.pole[1], mouse.pole[2]] : null; }

// The thesis's manipulation: pressing the thumb button with the pole tip near the sphere
// picks it up; it then keeps its offset to the tip; releasing sets it down on the ground
// below where it was.
function updateSphere(previousThumb) {
  const s = mouse.sphere;
  const tip = poleTip();
  const thumb = !!mouse.buttons.thumb;
  if (!s.held && thumb && !previousThumb && tip !== null) {
    const away = sub(s.centre, tip);
    if (Math.hypot(away[0], away[1], away[2]) <= mouse.reachMm) {
      s.held = true;
      s.offset = away;
    }
  }
  if (s.held && !thumb) {
    s.held = false;
    s.centre = [s.centre[0], s.centre[1], s.radius];
  }
  if (s.held) {
    s.centre = add(tip, s.offset);
  }
}

function line(ctx, canvas, a, b, style, width) {
  const pa = project(canvas, a), pb = project(canvas, b);
  ctx.strokeStyle = style; ctx.lineWidth = width;
  ctx.beginPath(); ctx.moveTo(pa.x, pa.y); ctx.lineTo(pb.x, pb.y); ctx.stroke();
}

function groundEllipse(ctx, canvas, centre, radius, style) {
  ctx.fillStyle = style;
  ctx.beginPath();
  for (let k = 0; k <= 32; k++) {
    const a = 2 * Math.PI * k / 32;
    const p = project(canvas, [centre[0] + radius * Math.cos(a), centre[1] + radius * Math.sin(a), 0]);
    if (k === 0) ctx.moveTo(p.x, p.y); else ctx.lineTo(p.x, p.y);
  }
  ctx.fill();
}

function drawSphere(ctx, canvas, s) {
  const c = project(canvas, s.centre);
  const r = FOCAL_PX * s.radius / c.depth;
  const g = ctx.createRadialGradient(c.x - 0.35 * r, c.y - 0.4 * r, 0.1 * r, c.x, c.y, r);
  g.addColorStop(0, s.held ? "#ffe2a8" : "#a8d0ff");
  g.addColorStop(1, s.held ? "#b86b00" : "#1f4f9a");
  ctx.fillStyle = g;
  ctx.beginPath(); ctx.arc(c.x, c.y, r, 0, 2 * Math.PI); ctx.fill();
}

function drawPole(ctx, canvas, tip) {
  const base = [tip[0], tip[1], 0];
  line(ctx, canvas, base, shadowOf(tip), "rgba(0,0,0,0.6)", 5);
  line(ctx, canvas, base, tip, "#f0f0f0", 5);
  const t = project(canvas, tip);
  ctx.fillStyle = mouse.buttons.thumb ? "#ffb347" : "#ff5050";
  ctx.beginPath(); ctx.arc(t.x, t.y, Math.max(3, FOCAL_PX * 5 / t.depth), 0, 2 * Math.PI); ctx.fill();
  const b = project(canvas, base);
  ctx.fillStyle = "#888"; ctx.beginPath(); ctx.arc(b.x, b.y, 3, 0, 2 * Math.PI); ctx.fill();
}

function draw() {
  const canvas = document.getElementById("scene");
  const ctx = canvas.getContext("2d");
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.fillStyle = "#20252b";
  ctx.beginPath();
  [[-1, -1], [1, -1], [1, 1], [-1, 1]].forEach(([i, j], k) => {
    const p = project(canvas, [i * GRID_HALF_MM, j * GRID_HALF_MM, 0]);
    if (k === 0) ctx.moveTo(p.x, p.y); else ctx.lineTo(p.x, p.y);
  });
  ctx.fill();
  for (let v = -GRID_HALF_MM; v <= GRID_HALF_MM + 1e-6; v += GRID_STEP_MM) {
    const style = Math.abs(v) < 1e-6 ? "#5a6673" : "#343c45";
    line(ctx, canvas, [v, -GRID_HALF_MM, 0], [v, GRID_HALF_MM, 0], style, 1);
    line(ctx, canvas, [-GRID_HALF_MM, v, 0], [GRID_HALF_MM, v, 0], style, 1);
  }
  const s = mouse.sphere;
  groundEllipse(ctx, canvas, shadowOf(s.centre), s.radius, "rgba(0,0,0,0.45)");
  const tip = poleTip();
  const items = [{ depth: project(canvas, s.centre).depth, paint: () => drawSphere(ctx, canvas, s) }];
  if (tip !== null) {
    items.push({ depth: project(canvas, tip).depth, paint: () => drawPole(ctx, canvas, tip) });
    const away = sub(s.centre, tip);
    if (s.held || Math.hypot(away[0], away[1], away[2]) <= mouse.reachMm) {
      line(ctx, canvas, tip, s.centre, "#ffd24a", 1.5);  // selection line (Fig. 4.9)
    }
  }
  items.sort((a, b) => b.depth - a.depth).forEach((item) => item.paint());
}

function setText(id, text) { document.getElementById(id).textContent = text; }

function showButton(name) {
  const el = document.getElementById("button-" + name);
  const pressed = !!mouse.buttons[name];
  el.textContent = pressed ? "pressed" : "up";
  el.className = pressed ? "pressed" : "up";
}

function onFrame(msg) {
  const previousThumb = !!mouse.buttons.thumb;
  mouse.pole = msg.pole;
  mouse.buttons = msg.buttons;
  mouse.lost = msg.lost;
  updateSphere(previousThumb);
  draw();
  // wall clock, as the server's time.time(), below a millisecond (Date.now() floors to
  // whole milliseconds, which can put the page before the server's own timestamps)
  const now = performance.timeOrigin + performance.now();
  mouse.latencyMs = now - msg.t_frame_ms;
  mouse.frames.push({ index: msg.index, pole: msg.pole.slice(), buttons: Object.assign({}, msg.buttons),
                      sphere: mouse.sphere.centre.slice(), held: mouse.sphere.held,
                      latency_ms: mouse.latencyMs, tracking_ms: msg.t_state_ms - msg.t_frame_ms });
  setText("frame", String(msg.index));
  setText("pole-xy", msg.pole[0].toFixed(1) + ", " + msg.pole[1].toFixed(1));
  setText("pole-height", msg.pole[2].toFixed(1));
  showButton("thumb"); showButton("little");
  setText("sphere-state", mouse.sphere.held ? "held" : "resting");
  setText("latency", mouse.latencyMs.toFixed(1));
  const status = document.getElementById("status");
  status.textContent = msg.lost ? "lost" : "ok";
  status.className = msg.lost ? "lost" : "";
}

function onImage(blob) {
  const img = document.getElementById("overlay");
  const old = img.src;
  img.src = URL.createObjectURL(blob);
  if (old.startsWith("blob:")) URL.revokeObjectURL(old);
  mouse.imageFrames += 1;
}

function connect() {
  const socket = new WebSocket("ws://" + location.host + "/ws");
  socket.binaryType = "blob";
  socket.onopen = () => { mouse.connected = true; };
  socket.onmessage = (event) => {
    if (typeof event.data !== "string") { onImage(event.data); return; }
    const msg = JSON.parse(event.data);
    if (msg.type === "hello") {
      mouse.sphere = { centre: [msg.sphere[0], msg.sphere[1], msg.sphere[2]], radius: msg.sphere[2],
                       held: false, offset: [0, 0, 0] };
      mouse.reachMm = msg.reach_mm;
      mouse.description = msg.description;
      setText("description", msg.description);
      draw();
    } else if (msg.type === "frame") {
      onFrame(msg);
    } else if (msg.type === "end") {
      mouse.ended = true;
      setText("description", mouse.description + " (ended after " + msg.frames + " frames)");
    } else if (msg.type === "error") {
      mouse.ended = true;
      mouse.error = msg.message;
      setText("description", mouse.description + " (stopped: " + msg.message + ")");
    }
  };
  socket.onclose = () => { mouse.connected = false; };
}

draw();
connect();
