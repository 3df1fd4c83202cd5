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
      tr.insertCell().textContent = u.name; tr.insertCell().textContent = u.role;
      const b = document.createElement("button"); b.textContent = word("web.button.remove", "Remove");
      b.addEventListener("click", async () => { try { await api("DELETE", "/api/users/" + encodeURIComponent(u.name)); loadUsers(); } catch (e) { show(e.message); } });
      tr.insertCell().appendChild(b);
    }
    const audit = await api("GET", "/api/audit");
    const ab = $("audit-table").tBodies[0];
    ab.textContent = "";
    for (const a of audit) { const tr = ab.insertRow(); [fmtTime(a.at), a.who, a.action, a.detail].forEach((v) => { tr.insertCell().textContent = v; }); }
  } catch (e) { show(e.message); }
}

export async function addUser(ev) {
  ev.preventDefault();
  try {
    await api("POST", "/api/users", { name: $("user-name").value, role: $("user-role").value, password: $("user-password").value });
    $("user-password").value = ""; show(word("web.msg.user_added", "user added"), true); loadUsers();
  } catch (e) { show(e.message); }
}
