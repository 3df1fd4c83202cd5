// The page's shared state, the element lookup, the message line and the
// one JSON API call every page makes.
import { say } from "./i18n.js";

export const state = {
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
  runNames: {},       // run id → "label (id)", once the store has it
  answeredAt: 0,      // when the operator last answered a prompt (ms)
  marks: [],          // [[t, label], ...]: when each level began
  words: {},          // the catalogue's web words in the chosen language
  language: "en",
  lastTime: 0,        // station time of the latest one-second values [s]
};

export const KEEP_S = 300;

export const $ = (id) => document.getElementById(id);

export function show(message, ok) {
  const m = $("message");
  m.textContent = message;
  m.className = ok ? "ok" : "";
  m.hidden = !message;
}

export async function api(method, path, body) {
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
