// The Users page (admins): users and the audit log.
import { $, api, show } from "./core.js";
import { fmtTime } from "./history.js";
import { word } from "./i18n.js";

export async function loadUsers() {
  try {
    const users = await api("GET", "/api/users");
    const body = $("users-table").tBodies[0];
    body.textContent = "";
    for (const u of users) {
      const tr = body.insertRow();
      tr.insertCell().textContent = u.name; tr.insertCell().textContent = word("web.role." + u.role, u.role);
      const b = document.createElement("button"); b.textContent = word("web.button.remove", "Remove");
      b.addEventListener("click", async () => { try { await api("DELETE", "/api/users/" + encodeURIComponent(u.name)); loadUsers(); } catch (e) { show(e.message); } });
      tr.insertCell().appendChild(b);
    }
    const audit = await api("GET", "/api/audit");
    const ab = $("audit-table").tBodies[0];
    ab.textContent = "";
    // The action by its word; its detail as it was recorded.
    for (const a of audit) {
      const tr = ab.insertRow();
      [fmtTime(a.at), word("web.who." + a.who, a.who), word("web.audit." + a.action, a.action), a.detail].forEach((v, k) => { const td = tr.insertCell(); td.textContent = v; if (k === 3) td.className = "detail"; });
    }
  } catch (e) { show(e.message); }
}

export async function addUser(ev) {
  ev.preventDefault();
  try {
    await api("POST", "/api/users", { name: $("user-name").value, role: $("user-role").value, password: $("user-password").value });
    $("user-password").value = ""; show(word("web.msg.user_added", "user added"), true); loadUsers();
  } catch (e) { show(e.message); }
}
