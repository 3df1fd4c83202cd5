// The Run page's live side: the event stream, the board, the prompt, the
// alarm banner, the status refresh, and the operator's actions.
import { $, api, KEEP_S, show, state } from "./core.js";
import { runName, showLinks, showReports } from "./history.js";
import { bannerText, etaText, fill, progressText, say, stateWord, stepText, word } from "./i18n.js";

export function connect() {
  if (state.events) return;
  // EventSource reconnects by itself and sends Last-Event-ID: the server replays what was missed.
  const es = new EventSource("/api/events");
  state.events = es;
  const on = (name, f) => es.addEventListener(name, (m) => { try { f(JSON.parse(m.data)); } catch (e) { console.error(e); } });
  on("run_started", (e) => {
    state.runId = e.run_id; state.serials = e.plan.serials; state.slots = e.plan.serials.length;
    state.history = state.serials.map(() => []); state.rate = []; state.values = 0; state.marks = [];
    $("event-log").textContent = ""; $("alarm").hidden = true; $("run-next").textContent = "";
    log(() => fill(e.resumed ? "web.log.resumed" : "web.log.started", "run " + e.run_id + (e.resumed ? " resumed" : " started"), { run: e.run_id }), e.published_ms);
    $("run-id").textContent = e.run_id; $("run-reports").textContent = ""; state.dirty = true;
    nameRun(e.run_id);
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
    state.stepNow = stepText(e.index, e.of, e.label, e.wording);
    $("progress").textContent = state.stepNow;
    $("run-progress").max = e.of; $("run-progress").value = e.index;
    // A level's start, marked on the curves with its level (from the
    // step's wording: no English label is read).
    const g = e.wording && e.wording.key === "step.level" && e.wording.args ? e.wording.args.g : null;
    if (g !== null && g !== undefined) { state.marks.push([state.lastTime, g + " g"]); while (state.marks.length > 200) state.marks.shift(); state.dirty = true; }
    log(() => say(e.wording, e.label), e.published_ms);
    // The station has gone on: the notice it handled is over.
    if ($("alarm").className === "notice") clearAlarm();
  });
  on("progress", (e) => { state.progressNow = e; $("progress").textContent = (state.stepNow || "") + progressText(e.phase, e.done, e.of); });
  on("prompt", (e) => {
    const text = promptText(e.fixtures, e.text);
    $("prompt-text").textContent = text; $("prompt").hidden = false; log(() => word("web.log.asked", "operator asked") + ": " + promptText(e.fixtures, e.text), e.published_ms);
  });
  on("prompt_answered", () => { $("prompt").hidden = true; });
  // A notice the station handled (a reading taken again) is no alarm: amber, gone at the next step.
  on("notice", (e) => { const m = say(e.wording, e.message); alarm(bannerText("notice", m), "notice"); log(() => bannerText("notice", say(e.wording, e.message)), e.published_ms); });
  // A fault is: red, on every page, until someone acknowledges it. An
  // abort someone asked for is no fault: its banner says aborted.
  on("fault", (e) => {
    const m = say(e.wording, e.reason);
    if (e.wording && (e.wording.key === "fault.aborted" || e.wording.key === "fault.aborted_web")) { alarm(bannerText("aborted", m), "aborted"); log(() => bannerText("aborted", say(e.wording, e.reason)), e.published_ms); return; }
    state.fault = m; alarm(bannerText("fault", m), "fault"); log(() => bannerText("fault", say(e.wording, e.reason)), e.published_ms);
  });
  on("unit_failed", (e) => {
    const m = fill("web.log.left_out", "slot " + (e.slot + 1) + " left out: " + e.reason,
      { slot: e.slot + 1, reason: say(reasonWording(e.code, e.args), e.reason) });
    alarm(m, "left-out");
    log(() => fill("web.log.left_out", "slot " + (e.slot + 1) + " left out: " + e.reason,
      { slot: e.slot + 1, reason: say(reasonWording(e.code, e.args), e.reason) }), e.published_ms);
  });
  on("run_finished", (e) => {
    const why = e.reason ? (state.fault && e.state === "faulted" ? state.fault : e.reason) : "";
    setRunState(stateWord(e.state) + (why ? ": " + why : ""));
    log(() => word("web.log.run", "run") + " " + stateWord(e.state) + (why ? ": " + why : ""), e.published_ms);
    if (e.state === "completed") $("run-progress").value = $("run-progress").max;
    // The run's outcome replaces the notices; a fault's banner stays until acknowledged.
    if (e.state === "completed") completedBanner(state.lastBoard);
    else if (e.state === "aborted") alarm(bannerText("aborted", why), "aborted");
    $("prompt").hidden = true;
    if (state.runId) {
      showReports($("run-reports"), state.runId);
      // The store takes the run's last results a moment after its end: asked again.
      const id = state.runId;
      for (const ms of [0, 2000, 5000]) setTimeout(() => { if (state.runId === id) offerNext(id); }, ms);
    }
    refreshStatus();
    // The runner lets go of the run a moment after its last event: the
    // board's outcomes, the banner's counts and the buttons follow then.
    setTimeout(refreshStatus, 1500);
  });
  on("health", () => refreshStatus());
}

// The run's event log, newest first (at most 200 lines), each line at the
// time the server published its event (a reload keeps the times). A line is
// kept with how it is worded (`text` may be a function), so a change of
// language words it again.
const logLines = [];
export function log(text, atMs) {
  const line = { word: typeof text === "function" ? text : () => text, at: atMs ? new Date(atMs) : new Date() };
  logLines.unshift(line);
  while (logLines.length > 200) logLines.pop();
  const li = document.createElement("li");
  li.textContent = clock(line.at) + "  " + line.word();
  const list = $("event-log");
  list.insertBefore(li, list.firstChild);
  while (list.children.length > 200) list.removeChild(list.lastChild);
}
function relog() {
  const list = $("event-log");
  list.textContent = "";
  for (const line of logLines) {
    const li = document.createElement("li");
    li.textContent = clock(line.at) + "  " + line.word();
    list.appendChild(li);
  }
}
document.addEventListener("spinbench:language", () => {
  relog();
  if (state.status) renderBoard(state.status.board);
  if (state.session) refreshStatus();
});

// A reason of an outcome ({code, args}) as a wording the page can fill
// (web.say.reason.<code>, or .<variant> when it has one).
export function reasonWording(code, args) {
  const variant = args && args.variant;
  return { key: "reason." + code + (variant ? "." + variant : ""), args: args || {} };
}

// The operator's prompt from the fixtures it asks for, in the page's
// language; the engine's text when a fixture has no word.
export function promptText(fixtures, text) {
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

// The banner above every page, by `kind`: "fault" (red,
// stays until someone acknowledges it: who and when go into the audit
// log), "notice" (amber, a reading the station took again: gone at the
// next step), "left-out" (amber, a slot left out: until the run ends),
// "aborted" (amber) and "done" (green, the run's outcome, which replaces
// any notice). A fault's banner is not replaced by anything but another fault.
export function alarm(text, kind) {
  const a = $("alarm");
  if (a.className === "fault" && !a.hidden && kind !== "fault") return;
  a.textContent = text; a.className = kind; a.hidden = false;
  if (kind === "fault") {
    const b = document.createElement("button");
    b.type = "button"; b.id = "ack-button"; b.textContent = word("web.banner.acknowledge", "Acknowledge");
    b.addEventListener("click", acknowledgeFault);
    a.append(" ", b);
  }
}

// The end of a completed run at a glance: how many
// instruments passed, were marginal, failed, were inconclusive or
// incomplete, coloured by the worst.
const OUTCOMES = ["pass", "marginal", "fail", "inconclusive", "incomplete"];
const WORST_FIRST = ["fail", "incomplete", "inconclusive", "marginal", "pass"];
function completedBanner(board) {
  const n = {};
  for (const s of board || []) if (s.serial && s.outcome) n[s.outcome] = (n[s.outcome] || 0) + 1;
  const parts = OUTCOMES.filter((o) => n[o]).map((o) => n[o] + " " + word("web.outcome." + o, o));
  const worst = WORST_FIRST.find((o) => n[o]);
  const text = word("web.banner.completed", "Run completed") + (parts.length ? " — " + parts.join(", ") : "");
  alarm(text, "done" + (worst && worst !== "pass" ? " " + worst : ""));
}

export function clearAlarm() {
  const a = $("alarm");
  a.hidden = true; a.className = ""; a.textContent = "";
}

async function acknowledgeFault() {
  try {
    await api("POST", "/api/run/acknowledge");
    clearAlarm();
    refreshStatus();
  } catch (e) { show(e.message); }
}

// The board: every slot's serial, mounting, latest output, state, points,
// k2 and K2 with U95 once fitted, outcome.
export function renderBoard(board) {
  const body = $("board").tBodies[0];
  body.textContent = "";
  const pm = (v) => v === null || v === undefined ? "—" : v[0].toFixed(3) + (v[1] === null ? "" : " ± " + v[1].toFixed(3));
  state.lastBoard = board || [];
  for (const s of board || []) {
    const tr = body.insertRow();
    tr.dataset.slot = s.slot;
    const k2 = (s.k2_ug_per_g2 || []).map((k) => k[0] + " " + pm([k[1], k[2]])).join(", ") || "—";
    [s.slot, s.serial, s.mount || "—", s.output_hz === null ? "—" : s.output_hz.toFixed(4), s.temperature_c === null ? "—" : s.temperature_c.toFixed(2),
      word("web.phase." + s.phase, s.phase) + (s.reason ? ": " + say(s.reason_code ? reasonWording(s.reason_code, s.reason_args) : null, s.reason) : ""), s.points + "/" + s.points_planned, k2, pm(s.big_k2_ug_per_g2), s.outcome ? word("web.outcome." + s.outcome, s.outcome) : "—",
      // What to do with the instrument now its outcome is known.
      s.outcome ? word("web.next." + s.outcome, "—") : "—"]
      .forEach((v, k) => {
        const td = tr.insertCell(); td.textContent = v;
        if (k === 5) td.className = "phase " + s.phase;
        if (k === 9 && s.outcome) td.className = s.outcome;
      });
  }
}

// After a run: Retest (with a confirmation naming the instruments) or
// Resume from the Run page, as the History page offers them.
export async function offerNext(id) {
  const box = $("run-next");
  box.textContent = "";
  try { showLinks(box, await api("GET", "/api/runs/" + encodeURIComponent(id)), "run-"); } catch (_) { /* the History page offers them */ }
}

export function push(list, item) {
  list.push(item);
  const cut = item[0] - KEEP_S;
  while (list.length && list[0][0] < cut) list.shift();
}

export function setRunState(text) { $("run-state").textContent = text; $("st-state").textContent = text; }

/** Show the run's label beside its id in the Run page's heading, once the store has it. */
async function nameRun(id) {
  if (state.runNames[id]) { $("run-id").textContent = state.runNames[id]; return; }
  $("run-id").textContent = id;
  try {
    const r = await api("GET", "/api/runs/" + encodeURIComponent(id));
    state.runNames[id] = runName(r);
    if (state.runId === id) $("run-id").textContent = runName(r);
  } catch (_) { /* not stored yet: the next status refresh asks again */ }
}

export async function refreshStatus() {
  if (!state.session) return;
  let s;
  try { s = await api("GET", "/api/status"); } catch (_) { return; }
  state.status = s;
  learnZone(s);
  const fix = (v, d) => (v === null || v === undefined) ? "—" : Number(v).toFixed(d);
  $("st-station").textContent = s.station + (s.simulated && !/virtual/.test(s.station) ? " (" + word("web.status.virtual", "virtual bench") + ")" : "");
  // The run by its label once known, else its id.
  $("st-run").textContent = s.run_id ? (state.runNames[s.run_id] || s.run_id) : word("web.status.none", "none");
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
  if (s.run_id) { state.runId = s.run_id; nameRun(s.run_id); }
  // The controls that apply now, and only those.
  const st = s.state || "";
  // An ended run (its record still being written) has nothing to control.
  const going = s.active && !s.ended;
  $("pause-button").hidden = !(going && (st === "running" || st === "prompting"));
  $("resume-button").hidden = !(going && st === "paused");
  $("abort-button").hidden = !going;
  renderBoard(s.board);
  renderPrediction(s.prediction, s.achieved);
  if (s.step) { $("run-progress").max = s.step.of; $("run-progress").value = st === "completed" ? s.step.of : s.step.index; }
  $("run-eta").textContent = going && s.eta_s ? etaText(s.eta_s)
    : (going ? word("web.eta.unknown", "time to go: not known yet") : stateWord(st));
  const why = s.reason ? say(s.reason_wording, s.reason) : "";
  if (s.fault && !s.fault_acknowledged && why) alarm(bannerText("fault", why), "fault");
  else if (s.fault && s.fault_acknowledged && $("alarm").className === "fault") clearAlarm();
  else if (why && st === "aborted") alarm(bannerText("aborted", why), "aborted");
  else if (st === "completed" && (["notice", "left-out"].includes($("alarm").className) || $("alarm").classList.contains("done"))) completedBanner(s.board);
  // The station's database: a line while it does not take the writes
  // (the run goes on measuring; its record follows when it is back).
  const db = s.store;
  if (db && !db.up) {
    const args = { events: db.queue_events, age: Math.round(db.queue_age_s) };
    $("store-health").textContent = fill("web.store.down",
      `The station's database is not answering: the run goes on measuring; ${args.events} events wait to be written (the oldest for ${args.age} s).`, args);
    $("store-health").hidden = false;
  } else $("store-health").hidden = true;
  if (s.state) $("run-state").textContent = stateWord(s.state);
  // A status fetched before an answer arrived still shows the old prompt: wait for the next.
  if (s.prompt && Date.now() - state.answeredAt > 2500) { $("prompt-text").textContent = promptText(s.prompt_fixtures, s.prompt); $("prompt").hidden = false; }
  else if (s.active && !s.prompt) $("prompt").hidden = true;
  if (s.step) {
    state.stepNow = stepText(s.step.index, s.step.of, s.step.label, s.step_wording);
    $("progress").textContent = state.stepNow + (s.active && s.progress ? progressText(s.progress.phase, s.progress.done, s.progress.of) : "");
  }
  waits(s);
}

// A prompt waits longer than this before the page raises a notice [s].
export const PROMPT_LATE_S = 600;

// The station's time zone, from the status.
export function learnZone(s) {
  if (typeof s.utc_offset_min === "number") { state.utcOffsetMin = s.utc_offset_min; state.timeZone = s.time_zone || "UTC"; }
}

// How long the operator's prompt and a pause have held the run, counted
// on the server's clock (the status carries its time).
export function waits(s) {
  const since = (t) => Math.max(0, Math.round((s.server_time_s || 0) - t));
  const span = (n) => n < 120 ? fill("web.wait.seconds", n + " s", { n }) : fill("web.wait.minutes", Math.floor(n / 60) + " min", { n: Math.floor(n / 60) });
  const box = $("prompt-waiting");
  if (s.prompt && s.prompt_since_s) {
    const n = since(s.prompt_since_s);
    const late = n >= PROMPT_LATE_S;
    box.textContent = late
      ? fill("web.prompt.late", "waiting for the operator for " + span(n) + ": the run is held until someone answers", { wait: span(n) })
      : fill("web.prompt.waiting", "waiting for the operator for " + span(n), { wait: span(n) });
    box.className = late ? "late" : "hint";
    box.dataset.waitedS = String(n);
    if (late && !state.lateSaid) { state.lateSaid = true; alarm(bannerText("notice", box.textContent), "notice"); log(bannerText("notice", box.textContent)); }
  } else { box.textContent = ""; state.lateSaid = false; }
  const held = $("held");
  if (s.active && s.state === "paused" && s.paused_since_s) {
    const n = since(s.paused_since_s);
    held.textContent = fill("web.run.held", "Held by the operator since " + clock(new Date(s.paused_since_s * 1000)) + " (" + span(n) + "): press Resume to go on",
      { since: clock(new Date(s.paused_since_s * 1000)), wait: span(n) });
    held.hidden = false;
  } else held.hidden = true;
}

// A time of day as the page shows it (UTC, said).
export function clock(date) {
  return new Date(date.getTime() + (state.utcOffsetMin || 0) * 60000).toISOString().slice(11, 19) + " " + (state.timeZone || "UTC");
}

// Where a run's median K2 U95 falls with 80 % probability ("" before the
// station has learned its instruments' spread).
export function predictionRange(range) {
  if (!range) return "";
  const vars = { low: Number(range[0]).toFixed(3), high: Number(range[1]).toFixed(3) };
  return fill("web.run.prediction_range", "; the run's median K2 U95 with 80 % probability in " + vars.low + "–" + vars.high + " µg/g² (its instruments' anomalies differ)", vars);
}

// The plan's prediction, and once the run ended what it achieved.
export function renderPrediction(p, a) {
  const box = $("run-prediction");
  if (!p) { box.hidden = true; return; }
  const f = (v, d) => (v === null || v === undefined ? "—" : Number(v).toFixed(d));
  const vars = {
    u95: f(p.k2_u95_ug_per_g2, 3), time: f(p.centrifuge_time_s, 0),
    achieved_u95: f(a && a.k2_u95_ug_per_g2, 3), achieved_time: f(a && a.centrifuge_time_s, 0),
    published_u95: f(p.published_k2_u95_ug_per_g2, 3), published_time: f(p.published_centrifuge_time_s, 0),
    runs: p.model_runs,
  };
  box.textContent = fill("web.run.prediction",
    "plan prediction: K2 U95 " + vars.u95 + " µg/g² predicted, " + vars.achieved_u95 + " achieved (median); centrifuge time " + vars.time + " s predicted, " + vars.achieved_time + " s achieved; the published plan: " + vars.published_u95 + " µg/g² in " + vars.published_time + " s (model from " + vars.runs + " run(s))", vars)
    + predictionRange(p.k2_u95_run_range_ug_per_g2)
    + (p.sequential_centrifuge_time_max_s == null ? "" : fill("web.run.prediction_sequential",
      "; the levels chosen by the data add at most " + f(p.sequential_centrifuge_time_max_s, 0) + " s of centrifuge time",
      { time: f(p.sequential_centrifuge_time_max_s, 0) }));
  box.hidden = false;
}

export async function answer(proceed) {
  state.answeredAt = Date.now();
  $("prompt").hidden = true;
  try { await api("POST", "/api/run/prompt", { proceed }); show(""); } catch (e) { show(e.message); }
}

export async function control(what) {
  try { await api("POST", "/api/run/" + what); show(word("web.control.done." + what, what), true); } catch (e) { show(e.message); }
}
