// fleet dashboard: draws the state document the server streams on /events (fleet/dashboard/live.py
// describes it: the FleetView of `fleet status --json`, plus each fleet's world map and history).
// Plain DOM and SVG, no build step.  Every text from the fleet goes in through textContent.
"use strict";

const SVG_NS = "http://www.w3.org/2000/svg";
const CONTACT_RECENT = 2.0; // s of sim time a contact stays highlighted
const LOG_REFRESH = 2000; // ms
const STATE_CLASSES = {
  running: "ok", starting: "warn", pending: "warn", degraded: "warn",
  failed: "bad", stopped: "bad", offline: "bad",
};

const view = { doc: null, fleet: null, selected: null, bounds: {}, params: [], logTimer: null };

// -- helpers ----------------------------------------------------------------------------------

function $(selector) { return document.querySelector(selector); }

function element(tag, attributes = {}, text = null) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  if (text !== null && text !== undefined) node.textContent = String(text);
  return node;
}

function shape(tag, attributes = {}) {
  const node = document.createElementNS(SVG_NS, tag);
  for (const [key, value] of Object.entries(attributes)) node.setAttribute(key, value);
  return node;
}

function row(cells, attributes = {}) {
  const tr = element("tr", attributes);
  for (const [name, text] of cells) tr.appendChild(element("td", { class: name }, text));
  return tr;
}

function fill(tbody, rows) { tbody.replaceChildren(...rows); }

function ago(seconds) {
  if (seconds === null || seconds === undefined) return "never";
  return `${duration(seconds)} ago`;
}

function duration(seconds) {
  if (seconds < 60) return `${seconds.toFixed(0)} s`;
  if (seconds < 3600) return `${(seconds / 60).toFixed(0)} min`;
  return `${(seconds / 3600).toFixed(1)} h`;
}

function formatPose(pose) {
  return pose ? `${pose.x.toFixed(2)}, ${pose.y.toFixed(2)}, ${pose.yaw.toFixed(2)}` : "";
}

function dataFlow(worldRobot) {
  if (!worldRobot) return "";
  const parts = [worldRobot.cmd_age === null || worldRobot.cmd_age === undefined
    ? "no cmd_vel yet" : `cmd_vel ${worldRobot.cmd_age.toFixed(1)} s ago`];
  if (worldRobot.odom_subscribers !== null && worldRobot.odom_subscribers !== undefined) {
    parts.push(`odom to ${worldRobot.odom_subscribers}`);
  }
  return parts.join(", ");
}

// -- the whole page, on each document ----------------------------------------------------------

function render() {
  const doc = view.doc;
  const fleets = [...new Set([...Object.keys(doc.maps), ...doc.robots.map((r) => r.fleet)])].sort();
  if (!fleets.includes(view.fleet)) view.fleet = fleets[0] || null;
  renderFleetSelect(fleets);
  renderSummary();
  renderMap();
  renderRobots();
  renderAgents();
  renderHistory();
  renderDetail();
}

function renderFleetSelect(fleets) {
  const select = $("#fleet-select");
  select.hidden = fleets.length < 2;
  if ([...select.options].map((o) => o.value).join() !== fleets.join()) {
    select.replaceChildren(...fleets.map((f) => element("option", { value: f }, f)));
  }
  select.value = view.fleet || "";
}

function renderSummary() {
  const robots = view.doc.robots.filter((r) => r.kind === "robot");
  const running = robots.filter((r) => r.state === "running").length;
  const agents = view.doc.agents.filter((a) => a.online).length;
  $("#summary").textContent =
    `${robots.length} robot${robots.length === 1 ? "" : "s"}, ${running} running; ` +
    `${agents} agent${agents === 1 ? "" : "s"} online`;
}

// -- map ------------------------------------------------------------------------------------------

function renderMap() {
  const svg = $("#map");
  const world = view.doc.maps[view.fleet];
  const line = $("#world-line");
  if (!world) {
    svg.replaceChildren();
    const simulated = view.doc.robots.some((r) => r.fleet === view.fleet && r.kind === "world");
    line.textContent = !view.fleet
      ? "no fleet is deployed"
      : simulated
        ? `fleet ${view.fleet}: its world has not reported yet`
        : `fleet ${view.fleet} runs no world: its robots are not simulated, so there is no map`;
    return;
  }
  const recent = new Set();
  for (const contact of world.contacts.last) {
    if (contact.sim_time >= world.sim_time - CONTACT_RECENT) { recent.add(contact.a); recent.add(contact.b); }
  }
  const rows = Object.fromEntries(view.doc.robots.filter((r) => r.fleet === view.fleet).map((r) => [r.name, r]));
  const layers = { obstacles: shape("g"), trails: shape("g"), rays: shape("g"), robots: shape("g"), labels: shape("g") };
  const points = [];

  for (const obstacle of world.obstacles) {
    const [x, y] = obstacle.position;
    const attributes = { class: "obstacle" + (recent.has(obstacle.name) ? " contact" : ""), "data-obstacle": obstacle.name };
    let body;
    if (obstacle.type === "cylinder") {
      body = shape("circle", { ...attributes, cx: x, cy: -y, r: obstacle.radius });
      points.push([x - obstacle.radius, y - obstacle.radius], [x + obstacle.radius, y + obstacle.radius]);
    } else {
      const [lx, ly] = obstacle.size;
      body = shape("rect", {
        ...attributes, x: -lx / 2, y: -ly / 2, width: lx, height: ly,
        transform: `translate(${x} ${-y}) rotate(${(-obstacle.yaw * 180) / Math.PI})`,
      });
      const [c, s] = [Math.cos(obstacle.yaw), Math.sin(obstacle.yaw)];
      for (const [cx, cy] of [[lx, ly], [lx, -ly], [-lx, ly], [-lx, -ly]]) {
        points.push([x + (c * cx - s * cy) / 2, y + (s * cx + c * cy) / 2]); // the box's corners
      }
    }
    body.appendChild(shape("title")).textContent = obstacle.name;
    layers.obstacles.appendChild(body);
  }

  for (const [name, robot] of Object.entries(world.robots)) {
    const { x, y, yaw } = robot.pose;
    const model = robot.model || { radius: 0.2 };
    const size = model.radius ?? Math.max(model.length, model.width) / 2;
    points.push([x - size, y - size], [x + size, y + size]);
    if ($("#show-trails").checked && robot.trail.length > 1) {
      layers.trails.appendChild(shape("polyline", { class: "trail", points: robot.trail.map(([tx, ty]) => `${tx},${-ty}`).join(" ") }));
    }
    if ($("#show-rays").checked) {
      for (const [hx, hy] of robot.scan_hits) {
        layers.rays.appendChild(shape("line", { class: "ray", x1: x, y1: -y, x2: hx, y2: -hy }));
      }
    }
    const state = rows[name] ? rows[name].state : "unknown";
    const classes = ["robot", STATE_CLASSES[state] || "bad"];
    if (recent.has(name)) classes.push("contact");
    if (view.selected && view.selected.fleet === view.fleet && view.selected.robot === name) classes.push("selected");
    const group = shape("g", {
      class: classes.join(" "), "data-robot": name,
      transform: `translate(${x} ${-y}) rotate(${(-yaw * 180) / Math.PI})`,
    });
    if (model.radius !== undefined && model.radius !== null) {
      group.appendChild(shape("circle", { class: "body", r: model.radius }));
    } else {
      group.appendChild(shape("rect", { class: "body", x: -model.length / 2, y: -model.width / 2, width: model.length, height: model.width }));
    }
    group.appendChild(shape("line", { class: "heading", x1: 0, y1: 0, x2: size * 1.7, y2: 0 }));
    group.appendChild(shape("title")).textContent = `${name}: ${state}`;
    group.addEventListener("click", () => select(view.fleet, name));
    layers.robots.appendChild(group);
    const label = shape("text", { class: "label", x: x, y: -y - size - 0.12, "text-anchor": "middle" });
    label.textContent = name;
    layers.labels.appendChild(label);
  }

  const box = viewBox(view.fleet, points);
  svg.setAttribute("viewBox", box.join(" "));
  svg.replaceChildren(grid(box), layers.obstacles, layers.trails, layers.rays, layers.robots, layers.labels);

  const count = world.contacts.count;
  let text = `${view.fleet}: sim time ${world.sim_time.toFixed(1)} s, real-time factor ${world.real_time_factor.toFixed(2)}, ` +
    `${Object.keys(world.robots).length} robots in the world, ${count} contact${count === 1 ? "" : "s"}`;
  const last = world.contacts.last[world.contacts.last.length - 1];
  if (last) text += ` (last ${last.a} with ${last.b} at ${last.sim_time.toFixed(1)} s)`;
  if (world.errors.length) text += `; error: ${world.errors[0].message}`;
  line.textContent = text;
  line.className = recent.size ? "contact" : "";
}

function viewBox(fleet, points) {
  // The area only grows (a fleet's map does not jump as robots move), with a margin.
  let [minX, minY, maxX, maxY] = view.bounds[fleet] || [Infinity, Infinity, -Infinity, -Infinity];
  for (const [x, y] of points) {
    minX = Math.min(minX, x); minY = Math.min(minY, y); maxX = Math.max(maxX, x); maxY = Math.max(maxY, y);
  }
  if (!Number.isFinite(minX)) [minX, minY, maxX, maxY] = [-5, -5, 5, 5];
  view.bounds[fleet] = [minX, minY, maxX, maxY];
  const margin = 0.6;
  return [minX - margin, -maxY - margin, maxX - minX + 2 * margin, maxY - minY + 2 * margin];
}

function grid([left, top, width, height]) {
  // A line every metre, the world's axes darker.
  const lines = shape("g");
  for (let x = Math.ceil(left); x <= left + width; x++) {
    lines.appendChild(shape("line", { class: x === 0 ? "axis" : "grid", x1: x, y1: top, x2: x, y2: top + height }));
  }
  for (let y = Math.ceil(top); y <= top + height; y++) {
    lines.appendChild(shape("line", { class: y === 0 ? "axis" : "grid", x1: left, y1: y, x2: left + width, y2: y }));
  }
  return lines;
}

// -- tables -------------------------------------------------------------------------------------

function renderRobots() {
  const maps = view.doc.maps;
  fill($("#robots tbody"), view.doc.robots.map((robot) => {
    const worldRobot = maps[robot.fleet] ? maps[robot.fleet].robots[robot.name] : null;
    const tr = row([
      ["fleet", robot.fleet],
      ["robot", robot.name],
      ["agent", robot.agent],
      ["state", robot.state],
      ["reason", robot.reason],
      ["nodes", robot.total ? `${robot.running}/${robot.total}` : ""],
      ["restarts", robot.restarts],
      ["battery", robot.battery === null ? "" : `${Math.round(robot.battery * 100)}%`],
      ["pose", formatPose(robot.pose)],
      ["flow", robot.kind === "robot" ? dataFlow(worldRobot) : ""],
    ], { "data-fleet": robot.fleet, "data-robot": robot.name });
    tr.querySelector(".state").classList.add(STATE_CLASSES[robot.state] || "bad");
    if (view.selected && view.selected.fleet === robot.fleet && view.selected.robot === robot.name) tr.classList.add("selected");
    tr.addEventListener("click", () => select(robot.fleet, robot.name));
    return tr;
  }));
}

function renderAgents() {
  fill($("#agents tbody"), view.doc.agents.map((agent) => {
    const tr = row([
      ["agent", agent.name],
      ["state", agent.online ? "online" : "offline"],
      ["up", agent.uptime === null || agent.uptime === undefined ? "" : duration(agent.uptime)],
      ["seen", agent.online ? "now" : ago(agent.last_seen)],
      ["host", agent.hostname],
      ["address", agent.address],
      ["cores", agent.cores || ""],
      ["fleets", agent.fleets.join(", ")],
    ], { "data-agent": agent.name });
    tr.querySelector(".state").classList.add(agent.online ? "ok" : "bad");
    return tr;
  }));
}

function renderHistory() {
  const rows = [];
  for (const [fleet, plans] of Object.entries(view.doc.history).sort()) {
    for (const plan of [...plans].reverse()) { // newest first
      // plan.generation is a string (19 digits); robot rows hold the nearest number to theirs.
      // Generations are deploy times in ns.
      const generation = Number(plan.generation);
      const now = view.doc.robots.filter((r) => r.fleet === fleet && r.generation === generation).map((r) => r.name);
      const robots = Object.keys(plan.robots);
      const tr = row([
        ["fleet", fleet],
        ["generation", new Date(generation / 1e6).toLocaleString()],
        ["robots", robots.length ? robots.join(", ") : "none (fleet down)"],
        ["current", now.join(", ")],
      ], { "data-generation": plan.generation });
      tr.querySelector(".generation").title = `generation ${plan.generation}`;
      rows.push(tr);
    }
  }
  fill($("#history tbody"), rows);
}

// -- one robot: nodes, parameters, logs ---------------------------------------------------------

function select(fleet, robot) {
  view.selected = { fleet, robot };
  view.params = [];
  $("#detail").hidden = false;
  $("#detail-title").textContent = `${robot} (fleet ${fleet})`;
  $("#logs").textContent = "loading...";
  fill($("#params tbody"), [row([["message", "loading..."]])]);
  clearInterval(view.logTimer);
  loadParams(fleet, robot);
  loadLogs(fleet, robot);
  view.logTimer = setInterval(() => loadLogs(fleet, robot), LOG_REFRESH);
  if (view.doc) render();
}

function closeDetail() {
  view.selected = null;
  clearInterval(view.logTimer);
  $("#detail").hidden = true;
  if (view.doc) render();
}

function isSelected(fleet, robot) {
  return view.selected && view.selected.fleet === fleet && view.selected.robot === robot;
}

async function getJson(path) {
  const response = await fetch(path);
  const data = await response.json();
  if (!response.ok) throw new Error(data.error || response.statusText);
  return data;
}

function robotPath(kind, fleet, robot) {
  return `api/${kind}/${encodeURIComponent(fleet)}/${encodeURIComponent(robot)}`;
}

async function loadLogs(fleet, robot) {
  try {
    const lines = await getJson(robotPath("logs", fleet, robot));
    if (!isSelected(fleet, robot)) return;
    const nodes = new Set(lines.map((l) => l.node));
    $("#logs").textContent = lines.map((l) => (nodes.size > 1 ? `[${l.node}] ${l.text}` : l.text)).join("\n") || "(no log lines)";
  } catch (error) {
    if (isSelected(fleet, robot)) $("#logs").textContent = `cannot read the logs: ${error.message}`;
  }
}

async function loadParams(fleet, robot) {
  try {
    const params = await getJson(robotPath("params", fleet, robot));
    if (!isSelected(fleet, robot)) return;
    fill($("#params tbody"), params.map((param) => paramRow(fleet, robot, param)));
    if (!params.length) fill($("#params tbody"), [row([["message", "(no parameters)"]])]);
  } catch (error) {
    if (isSelected(fleet, robot)) fill($("#params tbody"), [row([["message", `cannot read the parameters: ${error.message}`]])]);
  }
}

function paramRow(fleet, robot, param) {
  const tr = row([
    ["node", param.node],
    ["name", param.name],
    ["deployed", param.text + (param.override ? " (live override)" : "")],
  ], { "data-node": param.node, "data-param": param.name });
  const live = element("td", { class: "live" });
  const button = element("button", { type: "button" }, "read");
  button.addEventListener("click", async () => {
    live.textContent = "asking the node...";
    const path = `${robotPath("param", fleet, robot)}/${encodeURIComponent(param.node)}/${encodeURIComponent(param.name)}`;
    try {
      const reply = await getJson(path);
      live.textContent = reply.ok ? reply.text : `refused: ${reply.reason}`;
    } catch (error) {
      live.textContent = `failed: ${error.message}`;
    }
  });
  live.appendChild(button);
  tr.appendChild(live);
  return tr;
}

function renderDetail() {
  if (!view.selected) return;
  const robot = view.doc.robots.find((r) => isSelected(r.fleet, r.name));
  fill($("#nodes tbody"), (robot ? robot.nodes : []).map((node) => {
    const tr = row([
      ["node", node.name],
      ["state", node.state],
      ["pid", node.pid ?? ""],
      ["restarts", node.restarts],
      ["uptime", node.uptime === null || node.uptime === undefined ? "" : `${node.uptime.toFixed(0)} s`],
      ["exit", node.exit_code ?? ""],
    ], { "data-node": node.name });
    tr.querySelector(".state").classList.add(node.state === "running" ? "ok" : "warn");
    return tr;
  }));
}

// -- wiring -------------------------------------------------------------------------------------

function connect() {
  const badge = $("#connection");
  const source = new EventSource("events");
  source.onopen = () => { badge.textContent = "live"; badge.className = "badge online"; };
  source.onerror = () => { badge.textContent = "reconnecting"; badge.className = "badge offline"; };
  source.onmessage = (event) => { view.doc = JSON.parse(event.data); render(); };
}

$("#detail-close").addEventListener("click", closeDetail);
$("#fleet-select").addEventListener("change", (event) => { view.fleet = event.target.value; render(); });
for (const box of ["#show-rays", "#show-trails"]) $(box).addEventListener("change", () => view.doc && render());
connect();
