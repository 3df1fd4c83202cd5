// The Fleet page: every station on this store.
import { $, api, show, state } from "./core.js";
import { fmtTime } from "./history.js";
import { fill, stateWord, word } from "./i18n.js";

// The equipment register: every device with its calibration status;
// engineers and admins keep it (each change in the audit log).
// The fleet: every station on this store, refreshed every 3 s while shown.
export let fleetTimer = null;

export async function loadFleet() {
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
      const kind = word("web.fleet.kind." + st.kind.replace(/ /g, "_"), st.kind);
      // The latest run's outcomes at a glance, coloured by the worst.
      const n = st.last_run_outcomes || {};
      const last = ["pass", "marginal", "fail", "inconclusive", "incomplete"].filter((o) => n[o])
        .map((o) => n[o] + " " + word("web.outcome." + o, o)).join(", ") || "—";
      const worst = ["fail", "incomplete", "inconclusive", "marginal", "pass"].find((o) => n[o]) || "";
      [st.station + (st.this_station ? " *" : ""), kind, what, st.run_label || st.run_id || "—", progress, last, fpy, fmtTime(st.last_seen)]
        .forEach((v, k) => {
          const td = tr.insertCell(); td.textContent = v;
          if (k === 2) td.className = "fleet " + st.state;
          if (k === 5) { td.className = worst; td.dataset.outcomes = JSON.stringify(n); }
        });
      // An admin may take an offline station out of the list (audited).
      const act = tr.insertCell();
      if (st.state === "offline" && !st.this_station && state.session && state.session.role === "admin") {
        const b = document.createElement("button");
        b.textContent = word("web.fleet.retire", "Retire");
        b.className = "retire";
        b.onclick = () => retireStation(st.station);
        act.appendChild(b);
      }
    }
  } catch (e) { show(e.message); }
  fleetTimer = setTimeout(loadFleet, 3000);
}

async function retireStation(station) {
  const ask = fill("web.fleet.retire_confirm",
    "Take station " + station + " out of the Fleet list? Its runs stay; it comes back if it runs again.", { station });
  if (!confirm(ask)) return;
  try {
    await api("DELETE", "/api/fleet/" + encodeURIComponent(station));
    await loadFleet();
  } catch (e) { show(e.message); }
}
