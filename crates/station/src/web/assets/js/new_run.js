// The New run page: plans, the station config, the serials (a barcode
// scanner types them) and the start.
import { $, api, show, state } from "./core.js";
import { fill, say, word } from "./i18n.js";
import { predictionRange } from "./live.js";

export let plans = [];

export async function loadPlans() {
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

export async function savePlan(ev) {
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

export async function saveStation(ev) {
  ev.preventDefault();
  try { await api("PUT", "/api/station", $("station-text").value); show("station config saved", true); } catch (e) { show(e.message); }
}

// The chosen plan at a glance: range, levels, mountings,
// duration, the judged quantity, its limit and rule, and whether it can
// decide, before anything moves.
export function planSummary(plan) {
  const box = $("plan-summary");
  const s = plan && plan.summary;
  if (!s) { box.textContent = plan && plan.problem ? plan.problem : ""; box.className = "hint"; return; }
  const minutes = s.centrifuge_time_s == null ? "—" : Math.max(1, Math.round(s.centrifuge_time_s / 60));
  const vars = {
    range: s.range_g, levels: s.levels, passes: s.passes.join(" " + word("web.and", "and") + " "),
    minutes, measurand: s.measurand, limit: s.limit_ug_per_g2, rule: word("web.rule." + s.rule, s.rule),
    u95: s.k2_u95_ug_per_g2 == null ? "—" : s.k2_u95_ug_per_g2.toFixed(3),
  };
  const text = fill("web.plan.summary", "±" + vars.range + " g, " + vars.levels + " levels, mountings " + vars.passes + ", about " + minutes + " min of centrifuge time; judged: " + vars.measurand + " against " + vars.limit + " µg/g² (" + vars.rule + " rule); predicted K2 U95 " + vars.u95 + " µg/g²", vars);
  // Why it may not decide, in the page's language, shown in full.
  box.textContent = text + " — " + (s.can_decide
    ? word("web.plan.can_decide", "it can decide")
    : "⚠ " + (s.decision_warning
      ? say(s.decision_wording, s.decision_warning)
      : word("web.plan.cannot_decide", "⚠ it may not decide: the predicted uncertainty is too wide for the limit, or an instrument lacks a mounting")));
  box.title = "";
  box.className = s.can_decide ? "hint" : "hint warning";
  box.dataset.canDecide = String(s.can_decide);
}

export function fillSerials() {
  const plan = plans.find((p) => p.name === $("plan-select").value);
  planSummary(plan);
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
export function duplicateText(i, bare, j) {
  return fill("web.serial.duplicate", "slot " + i + ": '" + bare + "' is already in slot " + j, { slot: i, serial: bare, other: j });
}

// The bare serial of an entry ("P:A7" → "A7"), or an error for one that
// cannot be a serial: a bad mounting prefix, nothing after it, control
// characters, over 200 characters (the plan's MAX_NAME_CHARS).
export function bareSerial(v) {
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
export function scanned(i) {
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

// The K2 U95 target of the form, or null when empty; an error for one that is not a positive number.
function target() {
  const v = $("target-k2-u95").value.trim();
  if (!v) return { value: null };
  const x = Number(v);
  return Number.isFinite(x) && x > 0 ? { value: x } : { error: "'" + v + "' is not a positive K2 U95 in µg/g²" };
}

// Show the design for the target (POST /api/plans/{name}/design): nothing moves.
export async function predict(ev) {
  if (ev) ev.preventDefault();
  const t = target();
  const box = $("design-result");
  if (t.error) { show(t.error); return; }
  if (t.value === null) { box.hidden = true; return; }
  try {
    // The serials typed so far size the range of the run's median.
    const serials = {};
    for (let i = 1; i <= state.slots; i++) {
      const v = $("serial-" + i).value.trim();
      if (v) serials[String(i)] = v;
    }
    const d = await api("POST", "/api/plans/" + encodeURIComponent($("plan-select").value) + "/design", { target_k2_u95_ug_per_g2: t.value, serials });
    const vars = {
      levels: d.levels_g.length, down: d.down_levels_g.length, dwell: d.dwell_s,
      u95: d.k2_u95_ug_per_g2.toFixed(3), time: d.centrifuge_time_s.toFixed(0),
      published_u95: d.published_k2_u95_ug_per_g2 == null ? "—" : d.published_k2_u95_ug_per_g2.toFixed(3),
      published_time: d.published_centrifuge_time_s == null ? "—" : d.published_centrifuge_time_s.toFixed(0),
      source: d.model_source,
    };
    box.textContent = fill("web.msg.design", "designed: " + vars.levels + " levels, " + vars.down + " read again on the way down, " + vars.dwell + " s dwell — predicted K2 U95 " + vars.u95 + " µg/g² in " + vars.time + " s of centrifuge time; the published plan: " + vars.published_u95 + " µg/g² in " + vars.published_time + " s (" + vars.source + ")", vars)
      + predictionRange(d.k2_u95_run_range_ug_per_g2)
      + (d.decision_warning ? " ⚠ " + say(d.decision_wording, d.decision_warning) : "");
    box.classList.toggle("warning", !!d.decision_warning);
    box.hidden = false;
  } catch (e) { box.hidden = true; show(e.message); }
}

export async function startRun(ev) {
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
    const t = target();
    if (t.error) { show(t.error); return; }
    if (t.value !== null) request.target_k2_u95_ug_per_g2 = t.value;
    const reason = $("override-reason").value.trim();
    if (reason && state.session.role === "admin") request.override_overdue = reason;
    const r = await api("POST", "/api/runs", request);
    show(fill("web.log.started", "run " + r.run_id + " started", { run: r.run_id }), true);
    location.hash = "#run";
  } catch (e) { show(e.message); }
}
