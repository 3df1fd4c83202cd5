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
    for (const d of list) {
      const tr = body.insertRow();
      tr.dataset.role = d.role;
      [deviceWord(d.role), d.identity || "—", d.certificate || "—", d.calibrated_on || "—", d.due_on || "—", word("web.calibration." + d.status.replace(/ /g, "_"), d.status), d.updated_by || "—"]
        .forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 5) td.className = "cal " + d.status.replace(/ /g, "-"); });
      roles.add(new Option(deviceWord(d.role), d.role));
    }
    $("equipment-form").hidden = !(state.session && state.session.role !== "operator");
    // The centrifuge's signature the station learned (GET /api/station/signature).
    const sig = await api("GET", "/api/station/signature");
    $("signature-text").textContent = sig.text;
    $("signature-figure").innerHTML = sig.svg || "";
  } catch (e) { show(e.message); }
}

export async function saveEquipment(ev) {
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
