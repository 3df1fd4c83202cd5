// The History page: the runs, one run's results, its exclusions, links,
// retest and reports, and one serial's tests.
import { $, api, show, state } from "./core.js";
import { fill, stateWord, word } from "./i18n.js";

// A time [Unix s] in the station's zone, the zone said (
// the zone comes with the status: UTC until it is known).
export function fmtTime(t) { return new Date(t * 1000 + (state.utcOffsetMin || 0) * 60000).toISOString().replace("T", " ").slice(0, 16) + " " + (state.timeZone || "UTC"); }

// Fill a station selector from the fleet, keeping its choice; `all` adds
// "every station" first, else this server's station is the default.
export async function fillStations(id, all) {
  const select = $(id);
  const chosen = select.value;
  const fleet = await api("GET", "/api/fleet");
  select.textContent = "";
  if (all) select.add(new Option(word("web.option.every_station", "every station"), ""));
  for (const st of fleet) select.add(new Option(st.station, st.station));
  const mine = fleet.find((st) => st.this_station);
  select.value = chosen || (all ? "" : (mine ? mine.station : ""));
}

export async function loadHistory() {
  try {
    await fillStations("history-station", true);
    const station = $("history-station").value;
    const runs = await api("GET", "/api/runs" + (station ? "?station=" + encodeURIComponent(station) : ""));
    const body = $("runs-table").tBodies[0];
    body.textContent = "";
    for (const r of runs) {
      const tr = body.insertRow();
      const a = document.createElement("a");
      a.href = "#history"; a.textContent = r.label || r.id;
      // The label is how people name the run; the id stays beside it.
      if (r.label && r.label !== r.id) { a.title = r.id; }
      a.addEventListener("click", (ev) => { ev.preventDefault(); showRun(r.id); });
      const cell = tr.insertCell();
      cell.appendChild(a);
      if (r.label && r.label !== r.id) {
        const small = document.createElement("small"); small.className = "run-id"; small.textContent = " " + r.id; cell.appendChild(small);
      }
      [r.station, fmtTime(r.started_at), stateWord(r.state) + (r.reason ? ": " + r.reason : "") + (r.retest_of ? " (" + word("web.history.retest_of", "retest of") + " " + r.retest_of + ")" : ""), r.units, r.points].forEach((v) => { tr.insertCell().textContent = v; });
    }
  } catch (e) { show(e.message); }
}

/** "2026-11-24 · station 1 · #7 (run-…)": the label beside the id (the id alone for a run stored before labels). */
export function runName(r) {
  return r.label && r.label !== r.id ? r.label + " (" + r.id + ")" : r.id;
}

// The run the History page shows; a run still recorded as running is read
// again every 2 s while it is shown, so its end (stored a moment after the
// board says so) and its retest offer appear without a reload.
let shownRun = null;

// What a verdict judged, beside its outcome: the quantity, its value ± U95
// and the limit (a record from before decisions were recorded judged k2_max
// and does not say its limit).
export function judgedText(j, k2Max) {
  if (!j) return k2Max === null || k2Max === undefined ? "—" : "k2_max " + Number(k2Max).toFixed(3) + " µg/g²";
  const value = j.value_ug_per_g2 === null
    ? word("web.judged.not_measured", "not measured")
    : (j.value_ug_per_g2 >= 0 ? "+" : "") + j.value_ug_per_g2.toFixed(3) + (j.U95 === null ? "" : " ± " + j.U95.toFixed(3)) + " µg/g²";
  const rule = word("web.judged.rule." + j.rule, j.rule);
  return fill("web.judged.value", j.measurand + " " + value + " (limit " + j.limit_ug_per_g2 + " µg/g², " + rule + ")",
    { measurand: j.measurand, value, limit: j.limit_ug_per_g2, rule });
}

// Before a retest is started: what it takes and, for each inconclusive
// instrument, what would decide it and whether this retest is predicted to.
async function showRetestOffer(box, runId, idPrefix) {
  const list = document.createElement("ul");
  list.id = idPrefix + "retest-advice";
  box.appendChild(list);
  try {
    const offer = await api("GET", "/api/runs/" + encodeURIComponent(runId) + "/retest");
    const f = (v) => Number(v).toFixed(3);
    for (const a of offer.advice) {
      let line = fill("web.retest.advice", a.serial + ": " + f(a.value_ug_per_g2) + " ± " + f(a.U95) + " µg/g² against the limit " + a.limit_ug_per_g2 + " µg/g²; a U95 under " + f(a.deciding_u95_ug_per_g2) + " µg/g² decides it",
        { serial: a.serial, value: f(a.value_ug_per_g2), u95: f(a.U95), limit: a.limit_ug_per_g2, deciding: f(a.deciding_u95_ug_per_g2) });
      if (a.inconclusive_runs > 1) line += fill("web.retest.advice_tries", " (inconclusive in " + a.inconclusive_runs + " runs)", { n: a.inconclusive_runs });
      if (a.off_curve.length) line += fill("web.retest.advice_off_curve", "; off its curve at " + a.off_curve.join(", "), { levels: a.off_curve.join(", ") });
      const predicted = a.predicted_u95_ug_per_g2 === null ? "—" : f(a.predicted_u95_ug_per_g2);
      if (a.can_decide === true) line += fill("web.retest.advice_can", "; this retest is predicted to decide it (U95 " + predicted + " µg/g²)", { predicted });
      if (a.can_decide === false) line += fill("web.retest.advice_cannot", "; no retest is predicted to decide it (U95 " + predicted + " µg/g²): judge it by review or set it aside", { predicted });
      const li = document.createElement("li"); li.textContent = line; list.appendChild(li);
    }
    if (offer.sequential_levels_per_mounting) {
      const li = document.createElement("li");
      li.textContent = fill("web.retest.sequential", "Measured until the verdict is certain: up to " + offer.sequential_levels_per_mounting + " level(s) per mounting chosen by the data", { n: offer.sequential_levels_per_mounting });
      list.appendChild(li);
    }
  } catch (e) { show(e.message); }
}

export async function showRun(id) {
  shownRun = id;
  try {
    const r = await api("GET", "/api/runs/" + encodeURIComponent(id));
    if (r.state === "running") {
      setTimeout(() => { if (shownRun === id && !$("history").hidden) showRun(id); }, 2000);
    }
    const box = $("run-detail");
    box.textContent = "";
    const h = document.createElement("h3"); h.textContent = word("web.run.title", "Run") + " " + runName(r) + " — " + stateWord(r.state); box.appendChild(h);
    showLinks(box, r);
    showReports(box, r.id);
    const t = document.createElement("table");
    const head = ["serial", "slot", "mount", "radius [m]", "k1 [Hz/g]", "k2 [µg/g²]", "U95 (GUM)", "outcome", "judged", "reasons"];
    t.createTHead().insertRow().append(...head.map((x) => { const th = document.createElement("th"); th.textContent = word("web.head." + x, x); return th; }));
    const f = (v, d) => v === null ? "—" : Number(v).toFixed(d);
    for (const u of r.results) {
      const tr = t.insertRow();
      [u.serial, u.slot, u.mount, f(u.radius_m, 6), f(u.k1_hz_per_g, 6), f(u.k2_ug_per_g2, 3), f(u.k2_U95 ?? u.k2_ci95_half_ug_per_g2, 3), word("web.outcome." + u.outcome, u.outcome), judgedText(u.judged, u.k2_max_ug_per_g2), u.reasons]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 7) td.className = u.outcome; });
    }
    box.appendChild(t);
    if (state.session && state.session.role !== "operator" && r.results.length) box.appendChild(excludeForm(r));
  } catch (e) { show(e.message); }
}

// An engineer leaves a level of one instrument out of a finished run's
// reduction, with a reason; the server reduces and grades it again and
// keeps who, why and the figures before and after in the audit log.
export function excludeForm(r) {
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
export function showLinks(box, r, idPrefix = "") {
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
  // A run a crash left interrupted, or one aborted or faulted, goes on
  // from its journal (on the station that ran it: the server says if not).
  if (["interrupted", "aborted", "faulted"].includes(r.state)) {
    const b = document.createElement("button");
    b.id = idPrefix + "resume-run-button"; b.type = "button";
    b.textContent = word("web.resume.button", "Resume this run (its completed steps are kept)");
    b.addEventListener("click", async () => {
      try {
        const res = await api("POST", "/api/runs/" + encodeURIComponent(r.id) + "/resume");
        show(fill("web.resume.started", "run " + res.run_id + " goes on", { run: res.run_id }), true);
        location.hash = "#run";
      } catch (e) { show(e.message); }
    });
    box.appendChild(b);
  }
  // A completed run's instruments to test again (an aborted or faulted
  // run is resumed, not retested: its instruments were not all measured).
  if (r.state === "completed" && r.to_retest && r.to_retest.length) {
    const b = document.createElement("button");
    b.id = idPrefix + "retest-button"; b.type = "button";
    const serials = r.to_retest.join(", ");
    b.textContent = fill("web.retest.button", "Retest " + r.to_retest.length + " instrument(s): " + serials, { n: r.to_retest.length, serials });
    b.addEventListener("click", async () => {
      if (!confirm(fill("web.confirm.retest", "Start a retest of " + serials + " on this station?", { serials }))) return;
      try {
        const res = await api("POST", "/api/runs/" + encodeURIComponent(r.id) + "/retest");
        show(fill("web.retest.started", "retest " + res.run_id + " started: " + res.serials.join(", "), { run: res.run_id, serials: res.serials.join(", ") }), true);
        location.hash = "#run";
      } catch (e) { show(e.message); }
    });
    box.appendChild(b);
    showRetestOffer(box, r.id, idPrefix);
  }
}

export function showReports(box, id) {
  const p = document.createElement("p");
  p.className = "reports";
  p.append(word("web.report", "Report") + ": ");
  for (const f of ["pdf", "html", "xlsx", "csv"]) {
    const a = document.createElement("a");
    a.href = "/api/runs/" + encodeURIComponent(id) + "/report/" + f;
    a.id = "report-" + f; a.textContent = f.toUpperCase(); a.download = ""; // the server names the file: report-<label>-<id>.<ext>
    p.append(a, " ");
  }
  box.appendChild(p);
}

export async function findUnit(ev) {
  ev.preventDefault();
  const box = $("unit-result");
  box.textContent = "";
  try {
    const r = await api("GET", "/api/units/" + encodeURIComponent($("unit-serial").value.trim()));
    const ul = document.createElement("ul");
    for (const t of r.tests) {
      const li = document.createElement("li");
      li.textContent = t.run_id + " slot " + t.slot + ": " + word("web.outcome." + t.outcome, t.outcome) + ", " + judgedText(t.judged, t.k2_max_ug_per_g2);
      ul.appendChild(li);
    }
    box.appendChild(ul);
  } catch (e) { show(e.message); }
}
