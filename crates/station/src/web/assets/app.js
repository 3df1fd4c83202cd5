// The station page: a thin client of the JSON API (see /api/openapi.json)
// and of the live event stream (/api/events, server-sent events).
"use strict";

const state = {
  session: null,
  status: null,
  slots: 0,
  serials: [],
  history: [],        // per slot: [[t, value], ...]
  rate: [],           // [[t, rate], ...]
  values: 0,          // one-second events received
  dirty: false,
  events: null,
  runId: null,
  answeredAt: 0,      // when the operator last answered a prompt (ms)
  marks: [],          // [[t, label], ...]: when each level began
  words: {},          // the catalogue's web words in the chosen language
  language: "en",
  lastTime: 0,        // station time of the latest one-second values [s]
};
const KEEP_S = 300;
const $ = (id) => document.getElementById(id);

function show(message, ok) {
  const m = $("message");
  m.textContent = message;
  m.className = ok ? "ok" : "";
  m.hidden = !message;
}

async function api(method, path, body) {
  const headers = {};
  if (state.session) headers["X-CSRF-Token"] = state.session.csrf;
  if (body !== undefined) headers["Content-Type"] = typeof body === "string" ? "text/plain; charset=utf-8" : "application/json";
  const r = await fetch(path, {
    method, headers, credentials: "same-origin",
    body: body === undefined ? undefined : (typeof body === "string" ? body : JSON.stringify(body)),
  });
  const text = await r.text();
  let data = null;
  try { data = text ? JSON.parse(text) : null; } catch (_) { data = text; }
  // An error the server also gives as a wording is shown in the page's language.
  if (!r.ok) throw new Error(say(data && data.wording, (data && data.error) || (r.status + " " + r.statusText)));
  return data;
}

// The page's words in one language (GET /api/i18n/{language}): every
// element with data-i18n shows its entry; word() gives the rest.
async function setLanguage(language) {
  try {
    const r = await api("GET", "/api/i18n/" + encodeURIComponent(language));
    state.words = r.words; state.language = r.language;
    document.documentElement.lang = r.language;
    $("lang-select").value = r.language;
    for (const el of document.querySelectorAll("[data-i18n]")) {
      const w = state.words[el.dataset.i18n];
      if (w) el.textContent = w;
    }
    if (state.status) renderBoard(state.status.board);
    if (state.session) $("who").textContent = state.session.user + " (" + word("web.role." + state.session.role, state.session.role) + ")";
    // The last message was in the other language; the curves' labels redrawn.
    show("");
    state.dirty = true;
    // What the server words in the user's language, fetched again.
    if (state.session) {
      refreshStatus();
      if (!$("charts").hidden) loadCharts();
    }
  } catch (e) { show(e.message); }
}

function word(key, fallback) { return state.words[key] || fallback; }

// The page's words for `key` with each %{name} filled from `args` (a value
// that is a word of its own through web.arg.<name>.<value>); `fallback`
// (English) when the catalogue lacks the key or a value.
function fill(key, fallback, args) {
  const template = state.words[key];
  if (template === undefined) return fallback;
  let missing = false;
  const out = template.replace(/%\{(\w+)\}/g, (_, name) => {
    const v = (args || {})[name];
    if (v === undefined || v === null) { missing = true; return ""; }
    const w = state.words["web.arg." + name + "." + v];
    return w !== undefined ? w : String(v);
  });
  return missing ? fallback : out;
}

// A text the engine sent with its wording ({key, args}): the page's words
// for it, else the engine's own (English) text.
function say(wording, text) { return wording ? fill("web.say." + wording.key, text, wording.args) : text; }

// A device's role in the page's language ("fmu 2" → "计数模块 2").
function deviceWord(role) {
  const m = /^(.*?)(?: ([0-9]+))?$/.exec(role);
  const w = state.words["web.device." + m[1].replace(/ /g, "_")];
  return w === undefined ? role : w + (m[2] ? " " + m[2] : "");
}

// A run state's word (running, faulted, …).
function stateWord(st) { return st ? word("web.state." + st, st) : ""; }

// "about 3 min to go", in the page's language.
function etaText(s) {
  if (!s) return "";
  return s < 120 ? fill("web.eta.seconds", "about " + Math.round(s) + " s to go", { n: Math.round(s) })
    : fill("web.eta.minutes", "about " + Math.round(s / 60) + " min to go", { n: Math.round(s / 60) });
}

// "step 3 of 40: 5 g up (pass 1)", in the page's language.
function stepText(index, of, label, wording) {
  const text = say(wording, label);
  return fill("web.run.step", "step " + (index + 1) + " of " + of + ": " + text, { n: index + 1, of, label: text });
}

// " — averaging 12/30 s".
function progressText(phase, done, of) {
  return " — " + word("web.phase." + phase, phase) + " " + done + "/" + of + " s";
}

// A fault, a notice or an abort, with its word before it.
function bannerText(kind, text) { return word("web.banner." + kind, kind.toUpperCase() + ": ") + text; }

async function chooseLanguage() {
  const language = $("lang-select").value;
  if (state.session) {
    try { await api("PUT", "/api/session/language", { language }); } catch (e) { show(e.message); return; }
  }
  await setLanguage(language);
}

function route() {
  const page = (location.hash || "#status").slice(1);
  const loggedIn = !!state.session;
  for (const id of ["login", "status", "run", "new", "history", "charts", "equipment", "fleet", "users"]) {
    $(id).hidden = loggedIn ? id !== page : id !== "login";
  }
  $("nav").hidden = !loggedIn;
  $("logout-button").hidden = !loggedIn;
  for (const a of document.querySelectorAll("nav a")) a.classList.toggle("active", a.getAttribute("href") === "#" + page);
  if (!loggedIn) return;
  if (page === "new") loadPlans();
  if (page === "history") loadHistory();
  if (page === "charts") loadCharts();
  if (page === "equipment") loadEquipment();
  if (page === "fleet") loadFleet();
  if (page === "new") $("override-box").hidden = !(state.session && state.session.role === "admin");
  if (page === "users") loadUsers();
  if (page === "run") draw();
}

async function start() {
  window.addEventListener("hashchange", route);
  $("login-form").addEventListener("submit", login);
  $("logout-button").addEventListener("click", logout);
  $("new-form").addEventListener("submit", startRun);
  $("charts-form").addEventListener("submit", (ev) => { ev.preventDefault(); loadCharts(); });
  $("history-station").addEventListener("change", loadHistory);
  $("lang-select").addEventListener("change", chooseLanguage);
  $("equipment-form").addEventListener("submit", saveEquipment);
  $("plan-select").addEventListener("change", fillSerials);
  $("prompt-done").addEventListener("click", () => answer(true));
  $("prompt-abort").addEventListener("click", () => answer(false));
  $("pause-button").addEventListener("click", () => control("pause"));
  $("resume-button").addEventListener("click", () => control("resume"));
  $("abort-button").addEventListener("click", () => { if (confirm(word("web.confirm.abort", "Abort the run? The station stops safely."))) control("abort"); });
  $("user-form").addEventListener("submit", addUser);
  $("unit-form").addEventListener("submit", findUnit);
  $("plan-save").addEventListener("click", savePlan);
  $("station-save").addEventListener("click", saveStation);
  setInterval(() => { if (state.dirty && !$("run").hidden) draw(); }, 250);
  setInterval(refreshStatus, 2000);
  try { state.session = await api("GET", "/api/session"); } catch (_) { state.session = null; }
  afterLogin();
}

async function afterLogin() {
  $("who").textContent = state.session ? state.session.user + " (" + word("web.role." + state.session.role, state.session.role) + ")" : "";
  $("nav-users").hidden = !(state.session && state.session.role === "admin");
  route();
  if (state.session) { connect(); refreshStatus(); }
  // The user's language (chosen before, else the browser's), or the browser's before login.
  let language = /^zh(?!.*(TW|HK|Hant))/i.test(navigator.language || "") ? "zh-CN" : "en";
  if (state.session) {
    try { const s = await api("GET", "/api/session"); language = s.language || language; } catch (_) { /* keep the browser's */ }
  }
  await setLanguage(language);
}

async function login(ev) {
  ev.preventDefault();
  try {
    state.session = await api("POST", "/api/login", { user: $("login-user").value, password: $("login-password").value });
    $("login-password").value = "";
    show("");
    if (!location.hash || location.hash === "#login") location.hash = "#status";
    afterLogin();
  } catch (e) { show(e.message); }
}

async function logout() {
  try { await api("POST", "/api/logout"); } catch (_) { /* the session is gone either way */ }
  state.session = null;
  if (state.events) { state.events.close(); state.events = null; }
  afterLogin();
}

// ---- live data -------------------------------------------------------------

function connect() {
  if (state.events) return;
  // EventSource reconnects by itself and sends Last-Event-ID: the server replays what was missed.
  const es = new EventSource("/api/events");
  state.events = es;
  const on = (name, f) => es.addEventListener(name, (m) => { try { f(JSON.parse(m.data)); } catch (e) { console.error(e); } });
  on("run_started", (e) => {
    state.runId = e.run_id; state.serials = e.plan.serials; state.slots = e.plan.serials.length;
    state.history = state.serials.map(() => []); state.rate = []; state.values = 0; state.marks = [];
    $("event-log").textContent = ""; $("alarm").hidden = true;
    log(fill(e.resumed ? "web.log.resumed" : "web.log.started", "run " + e.run_id + (e.resumed ? " resumed" : " started"), { run: e.run_id }));
    $("run-id").textContent = e.run_id; $("run-reports").textContent = ""; state.dirty = true;
  });
  on("values", (e) => {
    if (state.history.length !== e.outputs_hz.length) state.history = e.outputs_hz.map(() => []);
    e.outputs_hz.forEach((v, i) => { if (v !== null) push(state.history[i], [e.time_s, v]); });
    state.temperatures = e.temperatures_c || [];
    push(state.rate, [e.time_s, e.rate_deg_s]);
    state.lastTime = e.time_s;
    state.values += 1;
    $("curves").dataset.values = String(state.values);
    state.dirty = true;
  });
  on("state_changed", (e) => setRunState(e.state));
  on("step_started", (e) => {
    $("progress").textContent = stepText(e.index, e.of, e.label, e.wording);
    $("run-progress").max = e.of; $("run-progress").value = e.index;
    // A level's start, marked on the curves (its label, e.g. "5 g Up (pass 1)").
    const level = /^(-?[0-9.]+ g)/.exec(e.label);
    if (level) { state.marks.push([state.lastTime, level[1]]); while (state.marks.length > 200) state.marks.shift(); state.dirty = true; }
    log(say(e.wording, e.label));
  });
  on("progress", (e) => { $("progress").textContent = $("progress").textContent.split(" — ")[0] + progressText(e.phase, e.done, e.of); });
  on("prompt", (e) => {
    const text = promptText(e.fixtures, e.text);
    $("prompt-text").textContent = text; $("prompt").hidden = false; log(word("web.log.asked", "operator asked") + ": " + text);
  });
  on("prompt_answered", () => { $("prompt").hidden = true; });
  on("notice", (e) => { const m = say(e.wording, e.message); show(m); alarm(bannerText("notice", m), false); log(bannerText("notice", m)); });
  on("fault", (e) => { const m = say(e.wording, e.reason); state.fault = m; show(bannerText("fault", m)); alarm(bannerText("fault", m), true); log(bannerText("fault", m)); });
  on("unit_failed", (e) => {
    const m = fill("web.log.left_out", "slot " + (e.slot + 1) + " left out: " + e.reason,
      { slot: e.slot + 1, reason: say(reasonWording(e.code, e.args), e.reason) });
    alarm(m, false); log(m);
  });
  on("run_finished", (e) => {
    const why = e.reason ? (state.fault && e.state === "faulted" ? state.fault : e.reason) : "";
    setRunState(stateWord(e.state) + (why ? ": " + why : ""));
    log(word("web.log.run", "run") + " " + stateWord(e.state) + (why ? ": " + why : ""));
    if (e.state === "completed") $("run-progress").value = $("run-progress").max;
    $("prompt").hidden = true;
    if (state.runId) showReports($("run-reports"), state.runId);
    refreshStatus();
  });
  on("health", () => refreshStatus());
}

// The run's event log, newest first (at most 200 lines).
function log(text) {
  const li = document.createElement("li");
  li.textContent = new Date().toISOString().slice(11, 19) + "  " + text;
  const list = $("event-log");
  list.insertBefore(li, list.firstChild);
  while (list.children.length > 200) list.removeChild(list.lastChild);
}

// A reason of an outcome ({code, args}) as a wording the page can fill
// (web.say.reason.<code>, or .<variant> when it has one).
function reasonWording(code, args) {
  const variant = args && args.variant;
  return { key: "reason." + code + (variant ? "." + variant : ""), args: args || {} };
}

// The operator's prompt from the fixtures it asks for, in the page's
// language; the engine's text when a fixture has no word.
function promptText(fixtures, text) {
  const name = (f) => {
    if (f === "Up" || f === "Down") return "tumble_" + f.toLowerCase();
    if (f && f.Arm) return "arm_" + f.Arm.toLowerCase();
    if (f && f.Crosswise) return f.Crosswise.as_on_arm ? "crosswise_as_on_arm" : "crosswise_inverted";
    return null;
  };
  const held = (fixtures || []).map((f, i) => [i, f ? name(f) : null]).filter(([, n]) => n !== null);
  if (!held.length || held.some(([, n]) => !state.words["web.arg.fixture." + n])) return text;
  const kinds = new Set(held.map(([, n]) => n));
  if (kinds.size === 1) return fill("web.say.prompt.mount_all", text, { fixture: held[0][1] });
  const list = held.map(([i, n]) => fill("web.say.prompt.mount_slot", "", { slot: i + 1, fixture: n })).join(word("web.list_separator", "; "));
  return fill("web.say.prompt.mount_list", text, { list });
}

// The alarm banner: a fault (red, stays) or a notice (amber).
function alarm(text, fault) {
  const a = $("alarm");
  a.textContent = text; a.className = fault ? "fault" : "notice"; a.hidden = false;
}

// The board: every slot's serial, mounting, latest output, state, points,
// k2 and K2 with U95 once fitted, outcome (issue 16, part 1).
function renderBoard(board) {
  const body = $("board").tBodies[0];
  body.textContent = "";
  const pm = (v) => v === null || v === undefined ? "—" : v[0].toFixed(3) + (v[1] === null ? "" : " ± " + v[1].toFixed(3));
  for (const s of board || []) {
    const tr = body.insertRow();
    tr.dataset.slot = s.slot;
    const k2 = (s.k2_ug_per_g2 || []).map((k) => k[0] + " " + pm([k[1], k[2]])).join(", ") || "—";
    [s.slot, s.serial, s.mount || "—", s.output_hz === null ? "—" : s.output_hz.toFixed(4), s.temperature_c === null ? "—" : s.temperature_c.toFixed(2),
      word("web.phase." + s.phase, s.phase) + (s.reason ? ": " + say(s.reason_code ? reasonWording(s.reason_code, s.reason_args) : null, s.reason) : ""), s.points + "/" + s.points_planned, k2, pm(s.big_k2_ug_per_g2), s.outcome ? word("web.outcome." + s.outcome, s.outcome) : "—"]
      .forEach((v, k) => {
        const td = tr.insertCell(); td.textContent = v;
        if (k === 5) td.className = "phase " + s.phase;
        if (k === 9 && s.outcome) td.className = s.outcome;
      });
  }
}

function push(list, item) {
  list.push(item);
  const cut = item[0] - KEEP_S;
  while (list.length && list[0][0] < cut) list.shift();
}

function setRunState(text) { $("run-state").textContent = text; $("st-state").textContent = text; }

async function refreshStatus() {
  if (!state.session) return;
  let s;
  try { s = await api("GET", "/api/status"); } catch (_) { return; }
  state.status = s;
  const fix = (v, d) => (v === null || v === undefined) ? "—" : Number(v).toFixed(d);
  $("st-station").textContent = s.station + (s.simulated && !/virtual/.test(s.station) ? " (" + word("web.status.virtual", "virtual bench") + ")" : "");
  $("st-run").textContent = s.run_id || word("web.status.none", "none");
  $("st-state").textContent = stateWord(s.state || "idle");
  $("st-rate").textContent = fill("web.status.rate", fix(s.rate_deg_s, 3) + " deg/s (demand " + fix(s.demand_deg_s, 3) + ")",
    { rate: fix(s.rate_deg_s, 3), demand: fix(s.demand_deg_s, 3) });
  $("st-g").textContent = fix(s.g_at_r0, 4) + " g";
  $("st-stable").textContent = s.on_speed === null || s.on_speed === undefined ? "—" : (s.on_speed ? word("web.status.stable", "stable") : word("web.status.not_stable", "not stable"));
  $("st-interlocks").textContent = s.interlocks_closed === null || s.interlocks_closed === undefined ? "—" : (s.interlocks_closed ? word("web.status.closed", "closed") : word("web.status.open", "OPEN"));
  $("st-supply").textContent = (s.supply || []).map((o, i) => fill("web.status.output", "out " + (i + 1), { n: i + 1 }) + ": " + o[0].toFixed(2) + " V " + o[1].toFixed(3) + " A").join("; ") || "—";
  const body = $("st-modules").tBodies[0];
  body.textContent = "";
  (s.modules || []).forEach((m, i) => {
    const tr = body.insertRow();
    [i + 1, m.frames, m.bad_crc, m.bad_tail, m.lost_ticks, m.reconnects].forEach((v) => { tr.insertCell().textContent = v; });
  });
  $("st-notices").textContent = "";
  (s.notices || []).forEach((n, i) => { const li = document.createElement("li"); li.textContent = say((s.notice_wordings || [])[i], n); $("st-notices").appendChild(li); });
  if (s.run_id) { $("run-id").textContent = s.run_id; state.runId = s.run_id; }
  // The controls that apply now, and only those.
  const st = s.state || "";
  $("pause-button").hidden = !(s.active && (st === "running" || st === "prompting"));
  $("resume-button").hidden = !(s.active && st === "paused");
  $("abort-button").hidden = !s.active;
  renderBoard(s.board);
  if (s.step) { $("run-progress").max = s.step[1]; $("run-progress").value = st === "completed" ? s.step[1] : s.step[0]; }
  $("run-eta").textContent = s.active && s.eta_s ? etaText(s.eta_s)
    : (s.active ? word("web.eta.unknown", "time to go: known once a step of each kind is done") : stateWord(st));
  const why = s.reason ? say(s.reason_wording, s.reason) : "";
  if (why && (st === "faulted" || st === "aborted")) alarm(bannerText(st === "faulted" ? "fault" : "aborted", why), st === "faulted");
  if (s.state) $("run-state").textContent = stateWord(s.state);
  // A status fetched before an answer arrived still shows the old prompt: wait for the next.
  if (s.prompt && Date.now() - state.answeredAt > 2500) { $("prompt-text").textContent = promptText(s.prompt_fixtures, s.prompt); $("prompt").hidden = false; }
  else if (s.active && !s.prompt) $("prompt").hidden = true;
  const eta = s.active && s.eta_s ? word("web.comma", ", ") + etaText(s.eta_s) : "";
  if (s.step) $("progress").textContent = stepText(s.step[0], s.step[1], s.step[2], s.step_wording)
    + (s.active && s.progress ? progressText(s.progress[0], s.progress[1], s.progress[2]) : "") + eta;
}

// The curves' text in the page's fonts (the CJK one when the browser has none).
const CANVAS_FONT = '11px "Noto Sans", "Noto Sans CJK SC", "Microsoft YaHei", "spinbench CJK", sans-serif';

function draw() {
  state.dirty = false;
  const c = $("curves"), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  g.font = CANVAS_FONT;
  const strip = 110;
  cell(g, 0, 0, c.width, strip, state.rate, word("web.plot.rate", "rate"), "deg/s", "#b00");
  // Only the slots that hold an instrument in this run.
  const slots = state.history.map((_, i) => i).filter((i) => state.serials[i] || state.history[i].length);
  const n = slots.length;
  if (!n) { g.fillStyle = "#333"; g.fillText(word("web.plot.waiting", "waiting for a run's one-second values…"), 20, strip + 30); return; }
  const cols = Math.ceil(Math.sqrt(n * c.width / (c.height - strip)));
  const rows = Math.ceil(n / cols);
  const w = c.width / cols, h = (c.height - strip) / rows;
  slots.forEach((slot, k) => {
    const t = (state.temperatures || [])[slot];
    const label = word("web.plot.slot", "slot") + " " + (slot + 1) + " " + (state.serials[slot] || "") + (t == null ? "" : "  " + t.toFixed(2) + " °C");
    cell(g, (k % cols) * w, strip + Math.floor(k / cols) * h, w, h, state.history[slot], label, "Hz", "#1d3557");
  });
}

function cell(g, x, y, w, h, pts, label, unit, color) {
  const left = 62, bottom = 14, top = 16;
  g.strokeStyle = "#ccc"; g.strokeRect(x + 1, y + 1, w - 2, h - 2);
  g.fillStyle = "#333"; g.fillText(label, x + 4, y + 12);
  if (pts.length) {
    const now = pts[pts.length - 1][1].toFixed(4) + " " + unit;
    g.fillText(now, x + w - 6 - g.measureText(now).width, y + 12);
  }
  if (pts.length < 2) return;
  let lo = Infinity, hi = -Infinity;
  for (const p of pts) { if (p[1] < lo) lo = p[1]; if (p[1] > hi) hi = p[1]; }
  if (hi === lo) { hi += Math.max(1e-9, Math.abs(hi) * 1e-6); lo -= Math.max(1e-9, Math.abs(lo) * 1e-6); }
  const px0 = x + left, pw = w - left - 6, py0 = y + top, ph = h - top - bottom - 4;
  const t1 = pts[pts.length - 1][0], t0 = t1 - KEEP_S;
  const X = (t) => px0 + pw * (t - t0) / KEEP_S, Y = (v) => py0 + ph - ph * (v - lo) / (hi - lo);
  // Grid and the value axis: four divisions, labelled at the left in the unit.
  const span = hi - lo, decimals = Math.min(6, Math.max(0, Math.ceil(-Math.log10(span / 4)) + 1));
  g.strokeStyle = "#eee"; g.fillStyle = "#555";
  for (let k = 0; k <= 4; k++) {
    const v = lo + span * k / 4, py = Y(v);
    g.beginPath(); g.moveTo(px0, py); g.lineTo(px0 + pw, py); g.stroke();
    const t = v.toFixed(decimals); g.fillText(t, px0 - 4 - g.measureText(t).width, py + 4);
  }
  // Time axis: a line every minute, labelled in seconds ago.
  for (let ago = 0; ago <= KEEP_S; ago += 60) {
    const px = X(t1 - ago);
    g.beginPath(); g.moveTo(px, py0); g.lineTo(px, py0 + ph); g.stroke();
    if (h > 60) { const t = ago ? "−" + ago + " s" : word("web.plot.now", "now"); g.fillText(t, px - g.measureText(t).width / 2, py0 + ph + bottom); }
  }
  // Level marks: a dashed line where each level began, its label on the rate strip.
  g.save(); g.setLineDash([3, 3]); g.strokeStyle = "#9ab";
  for (const [t, text] of state.marks) {
    if (t < t0 || t > t1) continue;
    const px = X(t);
    g.beginPath(); g.moveTo(px, py0); g.lineTo(px, py0 + ph); g.stroke();
    if (unit === "deg/s") { g.fillStyle = "#246"; g.fillText(text, px + 2, py0 + 10); }
  }
  g.restore();
  g.strokeStyle = color; g.beginPath();
  pts.forEach((p, k) => {
    const px = X(p[0]), py = Y(p[1]);
    if (k === 0) g.moveTo(px, py); else g.lineTo(px, py);
  });
  g.stroke();
}

// ---- actions ---------------------------------------------------------------

async function answer(proceed) {
  state.answeredAt = Date.now();
  $("prompt").hidden = true;
  try { await api("POST", "/api/run/prompt", { proceed }); show(""); } catch (e) { show(e.message); }
}

async function control(what) {
  try { await api("POST", "/api/run/" + what); show(what + ": done", true); } catch (e) { show(e.message); }
}

let plans = [];
async function loadPlans() {
  try {
    const r = await api("GET", "/api/plans");
    plans = r.plans; state.slots = r.slots;
    const sel = $("plan-select"), keep = sel.value;
    sel.textContent = "";
    for (const p of plans) {
      const o = document.createElement("option");
      o.value = p.name; o.textContent = p.name + (p.title ? " — " + p.title : "") + (p.problem ? " (invalid)" : "");
      sel.appendChild(o);
    }
    if (keep) sel.value = keep;
    fillSerials();
    const editor = state.session.role !== "operator";
    $("plan-editor").hidden = !editor;
    if (editor) {
      const st = await api("GET", "/api/station");
      $("station-text").value = st.toml;
      $("station-text").disabled = st.simulated;
      $("station-save").disabled = st.simulated;
      $("station-save").title = st.simulated ? word("web.hint.virtual_config", "the virtual bench's config is made from its devices") : "";
    }
  } catch (e) { show(e.message); }
}

async function savePlan(ev) {
  ev.preventDefault();
  const name = $("plan-name").value.trim();
  try {
    await api("PUT", "/api/plans/" + encodeURIComponent(name), $("plan-text").value);
    show(fill("web.msg.plan_saved", "plan " + name + " saved", { name }), true);
    await loadPlans();
    $("plan-select").value = name;
    fillSerials();
  } catch (e) { show(e.message); }
}

async function saveStation(ev) {
  ev.preventDefault();
  try { await api("PUT", "/api/station", $("station-text").value); show("station config saved", true); } catch (e) { show(e.message); }
}

function fillSerials() {
  const plan = plans.find((p) => p.name === $("plan-select").value);
  if (plan) { $("plan-name").value = plan.name; $("plan-text").value = plan.text; }
  const box = $("serials");
  box.textContent = "";
  for (let i = 1; i <= state.slots; i++) {
    const label = document.createElement("label");
    label.textContent = word("web.plot.slot", "slot") + " " + i + " ";
    const input = document.createElement("input");
    input.id = "serial-" + i;
    input.pattern = "^([PN]:)?\\s*[^\\s:].*$|^[^:]*$";
    input.title = word("web.hint.serial", "a serial number, optionally prefixed P: or N:");
    input.value = plan && plan.serials[String(i)] ? plan.serials[String(i)] : "";
    input.autocomplete = "off";
    input.addEventListener("keydown", (ev) => { if (ev.key === "Enter") { ev.preventDefault(); scanned(i); } });
    input.addEventListener("input", () => input.classList.remove("refused"));
    label.appendChild(input);
    box.appendChild(label);
  }
}

// "slot 3: 'A7' is already in slot 1".
function duplicateText(i, bare, j) {
  return fill("web.serial.duplicate", "slot " + i + ": '" + bare + "' is already in slot " + j, { slot: i, serial: bare, other: j });
}

// The bare serial of an entry ("P:A7" → "A7"), or an error for one that
// cannot be a serial: a bad mounting prefix, nothing after it, control
// characters, over 200 characters (the plan's MAX_NAME_CHARS).
function bareSerial(v) {
  if (/[\u0000-\u001f\u007f]/.test(v)) return { error: word("web.serial.control", "has control characters") };
  if (v.length > 200) return { error: word("web.serial.long", "is over 200 characters") };
  const colon = v.indexOf(":");
  if (colon < 0) return { bare: v.trim() };
  if (!/^[PN]$/.test(v.slice(0, colon).trim())) return { error: "'" + v.slice(0, colon) + ":' is not a mounting prefix; use P: or N:" };
  const bare = v.slice(colon + 1).trim();
  return bare ? { bare } : { error: word("web.serial.empty", "has no serial number after its mounting prefix") };
}

// A barcode scanner (keyboard wedge) types the serial and Enter: check it
// as it is scanned — a malformed serial or one already in another slot is
// refused and cleared, and the slot keeps the focus for the next scan;
// a good one moves the focus to the next slot (after the last, to Start).
function scanned(i) {
  const input = $("serial-" + i);
  const v = input.value.trim();
  input.classList.remove("refused");
  if (!v) { return; }
  const { bare, error } = bareSerial(v);
  let why = error ? fill("web.serial.refused", "slot " + i + ": '" + v + "' " + error, { slot: i, serial: v, why: error }) : "";
  if (!why) {
    for (let j = 1; j <= state.slots; j++) {
      const other = j === i ? "" : $("serial-" + j).value.trim();
      if (other && bareSerial(other).bare === bare) { why = duplicateText(i, bare, j); break; }
    }
  }
  if (why) {
    show(why + " — scan again");
    input.classList.add("refused");
    input.value = "";
    input.focus();
    return;
  }
  const next = i < state.slots ? $("serial-" + (i + 1)) : $("start-button");
  if (next) next.focus();
}

async function startRun(ev) {
  ev.preventDefault();
  const serials = {};
  const seen = {};
  for (let i = 1; i <= state.slots; i++) {
    const v = $("serial-" + i).value.trim();
    if (v) {
      const { bare, error } = bareSerial(v);
      if (error) { show(fill("web.serial.refused", "slot " + i + ": '" + v + "' " + error, { slot: i, serial: v, why: error })); return; }
      if (seen[bare]) { show(duplicateText(i, bare, seen[bare])); return; }
      seen[bare] = i;
      serials[String(i)] = v;
    }
  }
  if (!Object.keys(serials).length) { show(word("web.serial.none", "enter at least one serial number")); return; }
  try {
    const request = { plan: $("plan-select").value, serials };
    const reason = $("override-reason").value.trim();
    if (reason && state.session.role === "admin") request.override_overdue = reason;
    const r = await api("POST", "/api/runs", request);
    show(fill("web.log.started", "run " + r.run_id + " started", { run: r.run_id }), true);
    location.hash = "#run";
  } catch (e) { show(e.message); }
}

function fmtTime(t) { return new Date(t * 1000).toISOString().replace("T", " ").slice(0, 16) + " UTC"; }

// Fill a station selector from the fleet, keeping its choice; `all` adds
// "every station" first, else this server's station is the default.
async function fillStations(id, all) {
  const select = $(id);
  const chosen = select.value;
  const fleet = await api("GET", "/api/fleet");
  select.textContent = "";
  if (all) select.add(new Option(word("web.option.every_station", "every station"), ""));
  for (const st of fleet) select.add(new Option(st.station, st.station));
  const mine = fleet.find((st) => st.this_station);
  select.value = chosen || (all ? "" : (mine ? mine.station : ""));
}

async function loadHistory() {
  try {
    await fillStations("history-station", true);
    const station = $("history-station").value;
    const runs = await api("GET", "/api/runs" + (station ? "?station=" + encodeURIComponent(station) : ""));
    const body = $("runs-table").tBodies[0];
    body.textContent = "";
    for (const r of runs) {
      const tr = body.insertRow();
      const a = document.createElement("a");
      a.href = "#history"; a.textContent = r.id;
      a.addEventListener("click", (ev) => { ev.preventDefault(); showRun(r.id); });
      tr.insertCell().appendChild(a);
      [r.station, fmtTime(r.started_at), stateWord(r.state) + (r.reason ? ": " + r.reason : "") + (r.retest_of ? " (" + word("web.history.retest_of", "retest of") + " " + r.retest_of + ")" : ""), r.units, r.points].forEach((v) => { tr.insertCell().textContent = v; });
    }
  } catch (e) { show(e.message); }
}

async function showRun(id) {
  try {
    const r = await api("GET", "/api/runs/" + encodeURIComponent(id));
    const box = $("run-detail");
    box.textContent = "";
    const h = document.createElement("h3"); h.textContent = word("web.run.title", "Run") + " " + r.id + " — " + stateWord(r.state); box.appendChild(h);
    showLinks(box, r);
    showReports(box, r.id);
    const t = document.createElement("table");
    const head = ["serial", "slot", "mount", "radius [m]", "k1 [Hz/g]", "k2 [µg/g²]", "U95 (GUM)", "k2_max", "outcome", "reasons"];
    t.createTHead().insertRow().append(...head.map((x) => { const th = document.createElement("th"); th.textContent = word("web.head." + x, x); return th; }));
    const f = (v, d) => v === null ? "—" : Number(v).toFixed(d);
    for (const u of r.results) {
      const tr = t.insertRow();
      [u.serial, u.slot, u.mount, f(u.radius_m, 6), f(u.k1_hz_per_g, 6), f(u.k2_ug_per_g2, 3), f(u.k2_U95 ?? u.k2_ci95_half_ug_per_g2, 3), f(u.k2_max_ug_per_g2, 3), word("web.outcome." + u.outcome, u.outcome), u.reasons]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 8) td.className = v; });
    }
    box.appendChild(t);
    if (state.session && state.session.role !== "operator" && r.results.length) box.appendChild(excludeForm(r));
  } catch (e) { show(e.message); }
}

// An engineer leaves a level of one instrument out of a finished run's
// reduction, with a reason; the server reduces and grades it again and
// keeps who, why and the figures before and after in the audit log.
function excludeForm(r) {
  const form = document.createElement("form");
  form.id = "exclude-form";
  const field = (label, el) => { const l = document.createElement("label"); l.append(label + " ", el); form.append(l, " "); return el; };
  const serial = field(word("web.exclude.serial", "Leave out: serial"), document.createElement("select"));
  serial.id = "exclude-serial";
  for (const s of [...new Set(r.results.map((u) => u.serial))]) serial.add(new Option(s, s));
  const mount = field(word("web.exclude.mount", "mounting"), document.createElement("select"));
  mount.id = "exclude-mount";
  for (const m of ["P", "N"]) mount.add(new Option(m, m));
  const g = field(word("web.exclude.level", "level [g]"), document.createElement("input"));
  Object.assign(g, { id: "exclude-g", type: "number", min: "0", step: "any", required: true });
  const reason = field(word("web.exclude.reason", "reason"), document.createElement("input"));
  Object.assign(reason, { id: "exclude-reason", required: true, maxLength: 500, size: 40 });
  const button = document.createElement("button");
  button.type = "submit"; button.id = "exclude-button"; button.textContent = word("web.exclude.button", "Leave level out");
  // The same level put back (an exclusion withdrawn, with its reason).
  const back = document.createElement("button");
  back.type = "button"; back.id = "withdraw-button"; back.textContent = word("web.exclude.withdraw", "Put level back");
  form.append(button, " ", back);
  const send = async (path, said) => {
    try {
      const res = await api("POST", "/api/runs/" + encodeURIComponent(r.id) + path,
        { serial: serial.value, mount: mount.value, g: Number(g.value), reason: reason.value });
      show(res.serial + ": " + mount.value + " " + g.value + " g " + said + "; outcome " + res.outcome, true);
      await showRun(r.id);
    } catch (e) { show(e.message); }
  };
  form.addEventListener("submit", (ev) => { ev.preventDefault(); send("/exclusions", "left out"); });
  back.addEventListener("click", () => { if (form.reportValidity()) send("/exclusions/withdraw", "put back"); });
  return form;
}

// A retest's link to the run it retests, and the runs that retest this
// one; the Retest button when the run has ended with instruments to retest.
function showLinks(box, r) {
  const runLink = (id) => {
    const a = document.createElement("a");
    a.href = "#history"; a.textContent = id; a.className = "run-link";
    a.addEventListener("click", (ev) => { ev.preventDefault(); showRun(id); });
    return a;
  };
  if (r.retest_of) {
    const p = document.createElement("p"); p.id = "retest-of";
    p.append(word("web.history.retest_of_run", "Retest of run") + " ", runLink(r.retest_of));
    box.appendChild(p);
  }
  if (r.retested_by && r.retested_by.length) {
    const p = document.createElement("p"); p.id = "retested-by";
    p.append(word("web.history.retested_by_run", "Retested by run") + " ");
    r.retested_by.forEach((id, i) => { if (i) p.append(", "); p.append(runLink(id)); });
    box.appendChild(p);
  }
  if (r.state !== "running" && r.to_retest && r.to_retest.length) {
    const b = document.createElement("button");
    b.id = "retest-button"; b.type = "button";
    b.textContent = fill("web.retest.button", "Retest " + r.to_retest.length + " instrument(s): " + r.to_retest.join(", "), { n: r.to_retest.length, serials: r.to_retest.join(", ") });
    b.addEventListener("click", async () => {
      try {
        const res = await api("POST", "/api/runs/" + encodeURIComponent(r.id) + "/retest");
        show(fill("web.retest.started", "retest " + res.run_id + " started: " + res.serials.join(", "), { run: res.run_id, serials: res.serials.join(", ") }), true);
        location.hash = "#run";
      } catch (e) { show(e.message); }
    });
    box.appendChild(b);
  }
}

// The control charts across every run: the flags, each chart (its SVG,
// drawn by the server as in the batch report), the first-pass yields.
async function loadCharts() {
  try {
    await fillStations("charts-station", false);
    const station = $("charts-station").value;
    const c = await api("GET", "/api/control-charts?baseline_runs=" + encodeURIComponent($("baseline-runs").value || "10")
      + (station ? "&station=" + encodeURIComponent(station) : ""));
    const flags = $("flags-table").tBodies[0];
    flags.textContent = "";
    const figures = $("chart-figures");
    figures.textContent = "";
    for (const chart of c.charts) {
      for (const v of chart.violations) {
        const tr = flags.insertRow();
        tr.className = "flagged";
        [chart.quantity, v.point, v.run_id, Number(chart.points[v.point - 1].value).toFixed(6) + " " + chart.unit, v.says].forEach((x) => { tr.insertCell().textContent = x; });
      }
      // Every product chart; a radius chart only when a rule is broken.
      if (chart.svg && (chart.slot === null || chart.flagged)) {
        const fig = document.createElement("figure");
        fig.className = "control-chart";
        fig.dataset.quantity = chart.quantity;
        fig.dataset.flagged = chart.flagged;
        // The server's own SVG (plotters; no user text but the figure names).
        fig.innerHTML = chart.svg;
        figures.appendChild(fig);
      }
    }
    if (!flags.rows.length) { flags.insertRow().insertCell().textContent = fill("web.charts.no_rule", "no rule broken over " + c.runs + " runs", { runs: c.runs }); }
    const yields = $("yield-table").tBodies[0];
    yields.textContent = "";
    for (const y of c.yield_by_run.concat(c.yield_by_day)) {
      const tr = yields.insertRow();
      [y.label, y.first_tests, y.first_passes, y.yield === null ? "—" : (100 * y.yield).toFixed(1) + " %"].forEach((x) => { tr.insertCell().textContent = x; });
    }
  } catch (e) { show(e.message); }
}

// The equipment register: every device with its calibration status;
// engineers and admins keep it (each change in the audit log).
// The fleet: every station on this store, refreshed every 3 s while shown.
let fleetTimer = null;
async function loadFleet() {
  clearTimeout(fleetTimer);
  if ((location.hash || "#status") !== "#fleet" || !state.session) return;
  try {
    const list = await api("GET", "/api/fleet");
    const body = $("fleet-table").tBodies[0];
    body.textContent = "";
    for (const st of list) {
      const tr = body.insertRow();
      tr.dataset.station = st.station;
      tr.dataset.state = st.state;
      const what = st.state === "offline" ? word("web.fleet.offline", "offline") : stateWord(st.state);
      const progress = st.steps_total ? st.steps_done + " / " + st.steps_total : "—";
      const fpy = st.first_pass_yield === null || st.first_pass_yield === undefined ? "—"
        : (100 * st.first_pass_yield).toFixed(0) + " % (" + st.passed_today + "/" + st.tested_today + ")";
      [st.station + (st.this_station ? " *" : ""), what, st.run_id || "—", progress, fpy, fmtTime(st.last_seen)]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 1) td.className = "fleet " + st.state; });
    }
  } catch (e) { show(e.message); }
  fleetTimer = setTimeout(loadFleet, 3000);
}

async function loadEquipment() {
  try {
    const list = await api("GET", "/api/equipment");
    const body = $("equipment-table").tBodies[0];
    body.textContent = "";
    const roles = $("eq-role");
    roles.textContent = "";
    for (const d of list) {
      const tr = body.insertRow();
      tr.dataset.role = d.role;
      [deviceWord(d.role), d.identity || "—", d.certificate || "—", d.calibrated_on || "—", d.due_on || "—", word("web.calibration." + d.status.replace(/ /g, "_"), d.status), d.updated_by || "—"]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 5) td.className = "cal " + d.status.replace(/ /g, "-"); });
      roles.add(new Option(deviceWord(d.role), d.role));
    }
    $("equipment-form").hidden = !(state.session && state.session.role !== "operator");
  } catch (e) { show(e.message); }
}

async function saveEquipment(ev) {
  ev.preventDefault();
  try {
    const role = $("eq-role").value;
    await api("PUT", "/api/equipment/" + encodeURIComponent(role), {
      identity: $("eq-identity").value, certificate: $("eq-certificate").value,
      calibrated_on: $("eq-calibrated").value, due_on: $("eq-due").value,
    });
    show(role + ": saved", true);
    await loadEquipment();
  } catch (e) { show(e.message); }
}

function showReports(box, id) {
  const p = document.createElement("p");
  p.className = "reports";
  p.append(word("web.report", "Report") + ": ");
  for (const f of ["pdf", "html", "xlsx", "csv"]) {
    const a = document.createElement("a");
    a.href = "/api/runs/" + encodeURIComponent(id) + "/report/" + f;
    a.id = "report-" + f; a.textContent = f.toUpperCase(); a.download = "report-" + id + "." + f;
    p.append(a, " ");
  }
  box.appendChild(p);
}

async function findUnit(ev) {
  ev.preventDefault();
  const box = $("unit-result");
  box.textContent = "";
  try {
    const r = await api("GET", "/api/units/" + encodeURIComponent($("unit-serial").value.trim()));
    const ul = document.createElement("ul");
    for (const t of r.tests) {
      const li = document.createElement("li");
      li.textContent = t.run_id + " slot " + t.slot + ": " + t.outcome + ", k2_max " + (t.k2_max_ug_per_g2 === null ? "—" : t.k2_max_ug_per_g2.toFixed(3)) + " µg/g²";
      ul.appendChild(li);
    }
    box.appendChild(ul);
  } catch (e) { show(e.message); }
}

async function loadUsers() {
  try {
    const users = await api("GET", "/api/users");
    const body = $("users-table").tBodies[0];
    body.textContent = "";
    for (const u of users) {
      const tr = body.insertRow();
      tr.insertCell().textContent = u.name; tr.insertCell().textContent = u.role;
      const b = document.createElement("button"); b.textContent = word("web.button.remove", "Remove");
      b.addEventListener("click", async () => { try { await api("DELETE", "/api/users/" + encodeURIComponent(u.name)); loadUsers(); } catch (e) { show(e.message); } });
      tr.insertCell().appendChild(b);
    }
    const audit = await api("GET", "/api/audit");
    const ab = $("audit-table").tBodies[0];
    ab.textContent = "";
    for (const a of audit) { const tr = ab.insertRow(); [fmtTime(a.at), a.who, a.action, a.detail].forEach((v) => { tr.insertCell().textContent = v; }); }
  } catch (e) { show(e.message); }
}

async function addUser(ev) {
  ev.preventDefault();
  try {
    await api("POST", "/api/users", { name: $("user-name").value, role: $("user-role").value, password: $("user-password").value });
    $("user-password").value = ""; show(word("web.msg.user_added", "user added"), true); loadUsers();
  } catch (e) { show(e.message); }
}

start();
