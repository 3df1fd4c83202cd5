// The station page: a thin client of the JSON API (see /api/openapi.json)
// and of the live event stream (/api/events, server-sent events), as ES
// modules with no build step: this entry routes between the pages (one
// module each in js/: new_run, history, control_charts, fleet, equipment,
// users; the Run page's live and charts) over the shared core and i18n,
// and logs in and out.
import { draw } from "./js/charts.js";
import { loadCharts } from "./js/control_charts.js";
import { $, api, show, state } from "./js/core.js";
import { loadEquipment, saveEquipment } from "./js/equipment.js";
import { loadFleet } from "./js/fleet.js";
import { findUnit, loadHistory } from "./js/history.js";
import { chooseLanguage, setLanguage, word } from "./js/i18n.js";
import { answer, connect, control, refreshStatus } from "./js/live.js";
import { fillSerials, loadPlans, predict, savePlan, saveStation, startRun } from "./js/new_run.js";
import { addUser, loadUsers } from "./js/users.js";

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
  $("design-button").addEventListener("click", predict);
  $("charts-form").addEventListener("submit", (ev) => { ev.preventDefault(); loadCharts(); });
  $("history-station").addEventListener("change", loadHistory);
  $("lang-select").addEventListener("change", chooseLanguage);
  $("equipment-form").addEventListener("submit", saveEquipment);
  $("plan-select").addEventListener("change", fillSerials);
  $("prompt-done").addEventListener("click", () => answer(true));
  // The prompt's Abort sits beside Done: it asks first.
  $("prompt-abort").addEventListener("click", () => { if (confirm(word("web.confirm.abort", "Abort the run? The station stops safely."))) answer(false); });
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
  // The user's language (chosen before, else the browser's), or the browser's before login.
  let language = /^zh(?!.*(TW|HK|Hant))/i.test(navigator.language || "") ? "zh-CN" : "en";
  if (state.session) {
    try { const s = await api("GET", "/api/session"); language = s.language || language; } catch (_) { /* keep the browser's */ }
  }
  // The words first: the event stream's replay is worded in the user's language.
  await setLanguage(language);
  if (state.session) { connect(); refreshStatus(); }
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

start();
