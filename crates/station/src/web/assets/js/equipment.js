// The Equipment page: the register of the station's devices.
import { $, api, show, state } from "./core.js";
import { deviceWord, fill, word } from "./i18n.js";

export async function loadEquipment() {
  try {
    const list = await api("GET", "/api/equipment");
    const body = $("equipment-table").tBodies[0];
    body.textContent = "";
    const roles = $("eq-role");
    roles.textContent = "";
    // Whose register this is: each station of a fleet keeps its own.
    const station = list.length ? list[0].station : "";
    $("equipment-station").textContent = fill("web.equipment.of_station",
      "Station " + station + ": its own devices (each station of a fleet keeps its own register).", { station });
    const engineer = !!(state.session && state.session.role !== "operator");
    let unregistered = 0;
    for (const d of list) {
      const tr = body.insertRow();
      tr.dataset.role = d.role;
      // A device not in the register shows the identity the station read
      // from it (its *IDN?), for an engineer to confirm.
      const identity = d.identity || (d.read_identity ? fill("web.equipment.read", "read: " + d.read_identity, { identity: d.read_identity }) : "—");
      [deviceWord(d.role), identity, d.certificate || "—", d.calibrated_on || "—", d.due_on || "—", word("web.calibration." + d.status.replace(/ /g, "_"), d.status), d.updated_by || "—"]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 5) td.className = "cal " + d.status.replace(/ /g, "-"); });
      const act = tr.insertCell();
      if (!d.identity) {
        unregistered += 1;
        if (engineer) {
          const b = document.createElement("button");
          b.type = "button"; b.className = "register";
          b.textContent = word("web.equipment.register", "Register…");
          b.addEventListener("click", () => prefill(d));
          act.appendChild(b);
        }
      }
      roles.add(new Option(deviceWord(d.role), d.role));
    }
    const note = $("equipment-unregistered");
    note.textContent = unregistered ? fill("web.equipment.unregistered",
      unregistered + " of the station's devices are not in the register: the identities the station read are shown; an engineer registers each with its certificate and dates (Register…).",
      { n: unregistered }) : "";
    note.hidden = !unregistered;
    $("equipment-form").hidden = !engineer;
    // The centrifuge's signature the station learned (GET /api/station/signature).
    const sig = await api("GET", "/api/station/signature");
    $("signature-text").textContent = sig.text;
    $("signature-figure").innerHTML = sig.svg || "";
  } catch (e) { show(e.message); }
}

// The form filled with a device's role and the identity the station read,
// for an engineer to add the certificate and dates and save.
export function prefill(d) {
  $("eq-role").value = d.role;
  $("eq-identity").value = d.read_identity || "";
  $("eq-certificate").focus();
}

export async function saveEquipment(ev) {
  ev.preventDefault();
  try {
    const role = $("eq-role").value;
    await api("PUT", "/api/equipment/" + encodeURIComponent(role), {
      identity: $("eq-identity").value, certificate: $("eq-certificate").value,
      calibrated_on: $("eq-calibrated").value, due_on: $("eq-due").value,
    });
    show(fill("web.equipment.saved", role + ": saved", { role: deviceWord(role) }), true);
    await loadEquipment();
  } catch (e) { show(e.message); }
}
