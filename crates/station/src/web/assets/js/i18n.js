// The page's words in the user's language: the catalogue from
// GET /api/i18n/{language}, filled wordings, and the texts built from them.
import { $, api, show, state } from "./core.js";

// The page's words in one language (GET /api/i18n/{language}): every
// element with data-i18n shows its entry; word() gives the rest.
export async function setLanguage(language) {
  try {
    const r = await api("GET", "/api/i18n/" + encodeURIComponent(language));
    state.words = r.words; state.language = r.language;
    document.documentElement.lang = r.language;
    $("lang-select").value = r.language;
    for (const el of document.querySelectorAll("[data-i18n]")) {
      const w = state.words[el.dataset.i18n];
      if (w) el.textContent = w;
    }
    if (state.session) $("who").textContent = state.session.user + " (" + word("web.role." + state.session.role, state.session.role) + ")";
    // The last message was in the other language; the curves' labels redrawn.
    show("");
    state.dirty = true;
    // The pages word again what they showed (the board, the event log,
    // what the server words: the status, the charts): announced, so this
    // module knows no page.
    document.dispatchEvent(new CustomEvent("spinbench:language", { detail: r.language }));
  } catch (e) { show(e.message); }
}

export function word(key, fallback) { return state.words[key] || fallback; }

// The page's words for `key` with each %{name} filled from `args` (a value
// that is a word of its own through web.arg.<name>.<value>); `fallback`
// (English) when the catalogue lacks the key or a value.
export function fill(key, fallback, args) {
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
export function say(wording, text) { return wording ? fill("web.say." + wording.key, text, wording.args) : text; }

// A device's role in the page's language ("fmu 2" → "计数模块 2").
export function deviceWord(role) {
  const m = /^(.*?)(?: ([0-9]+))?$/.exec(role);
  const w = state.words["web.device." + m[1].replace(/ /g, "_")];
  return w === undefined ? role : w + (m[2] ? " " + m[2] : "");
}

// A run state's word (running, faulted, …).
export function stateWord(st) { return st ? word("web.state." + st, st) : ""; }

// "about 3 min to go", in the page's language.
export function etaText(s) {
  if (!s) return "";
  return s < 120 ? fill("web.eta.seconds", "about " + Math.round(s) + " s to go", { n: Math.round(s) })
    : fill("web.eta.minutes", "about " + Math.round(s / 60) + " min to go", { n: Math.round(s / 60) });
}

// "step 3 of 40: 5 g up (pass 1)", in the page's language.
export function stepText(index, of, label, wording) {
  const text = say(wording, label);
  return fill("web.run.step", "step " + (index + 1) + " of " + of + ": " + text, { n: index + 1, of, label: text });
}

// " — averaging 12/30 s".
export function progressText(phase, done, of) {
  return " — " + word("web.phase." + phase, phase) + " " + done + "/" + of + " s";
}

// A fault, a notice or an abort, with its word before it.
export function bannerText(kind, text) { return word("web.banner." + kind, kind.toUpperCase() + ": ") + text; }

export async function chooseLanguage() {
  const language = $("lang-select").value;
  if (state.session) {
    try { await api("PUT", "/api/session/language", { language }); } catch (e) { show(e.message); return; }
  }
  await setLanguage(language);
}
