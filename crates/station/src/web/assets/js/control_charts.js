// The Charts page: the control charts across runs, drawn by the server.
import { $, api, show } from "./core.js";
import { fillStations } from "./history.js";
import { fill } from "./i18n.js";

// The charts worded again by the server in a new language, when shown.
document.addEventListener("spinbench:language", () => { if (!$("charts").hidden) loadCharts(); });

// The control charts across every run: the flags, each chart (its SVG,
// drawn by the server as in the batch report), the first-pass yields.
export async function loadCharts() {
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
        // The run by its label and the instrument by its serial.
        tr.dataset.runId = v.run_id;
        [chart.quantity, v.point, v.run_label, v.serial || "—", Number(chart.points[v.point - 1].value).toFixed(6) + " " + chart.unit, v.says].forEach((x) => { tr.insertCell().textContent = x; });
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
