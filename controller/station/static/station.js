// The cell page: polls /api/status four times a second and updates the page in place; the
// action buttons POST with the page's CSRF token. No external assets.
"use strict";
(function () {
  const csrf = document.querySelector('meta[name="csrf-token"]').content;
  const $ = (id) => document.getElementById(id);
  let lastRecord = null;
  let lastAwaiting = null;

  function setText(id, value) {
    const el = $(id);
    if (el && el.textContent !== String(value)) el.textContent = String(value);
  }

  function figure(src, caption) {
    const fig = document.createElement("figure");
    const img = document.createElement("img");
    img.src = src; img.alt = caption; img.className = "shot";
    const cap = document.createElement("figcaption");
    cap.textContent = caption;
    fig.append(img, cap);
    return fig;
  }

  function recordName(path) {
    if (!path) return null;
    const parts = path.split("/");
    return parts[parts.length - 1];
  }

  function showConfirm(st) {
    const panel = $("confirm");
    const waiting = st.awaiting_confirmation;
    panel.hidden = !waiting;
    const key = waiting ? JSON.stringify(waiting) + st.record : null;
    if (key === lastAwaiting) return;
    lastAwaiting = key;
    const box = $("confirm-images");
    box.replaceChildren();
    if (!waiting) return;
    setText("confirm-summary", `${waiting.weld_points} weld points, ${waiting.length_mm} mm, ` +
      `from ${waiting.first_mm.join(", ")} to ${waiting.last_mm.join(", ")} mm ` +
      `(answer within ${waiting.timeout_s} s)`);
    const rec = recordName(st.record);
    if (rec) {
      for (const v of st.views || []) {
        box.append(figure(`/records/${rec}/path/${v}.png?t=${Date.now()}`, `${v}: planned torch path`));
      }
    }
  }

  function showLast(st) {
    const last = st.last_cycle;
    if (!last) return;
    setText("last-cycle", last.status + (last.reason ? ": " + last.reason : ""));
    const rec = recordName(last.record);
    if (rec === lastRecord) return;
    lastRecord = rec;
    const box = $("last-images");
    box.replaceChildren();
    if (!rec) return;
    for (const v of last.views || []) {
      box.append(figure(`/records/${rec}/files/${v}_overlay.png`, `${v}: detected seam`));
    }
    if (last.status === "done") {
      box.append(figure(`/records/${rec}/files/seam_plot.png`, "3D seam and torch-tip path"));
    }
    const link = $("last-link");
    link.replaceChildren();
    const a = document.createElement("a");
    a.href = `/records/${rec}`; a.textContent = "open the record " + rec; a.id = "last-record-link";
    link.append(a);
  }

  async function poll() {
    try {
      const r = await fetch("/api/status", {credentials: "same-origin", cache: "no-store"});
      if (r.status === 401) { window.location = "/login"; return; }
      const st = await r.json();
      setText("state", st.state);
      $("state").dataset.state = st.state;
      $("paused").hidden = !st.paused;
      setText("job", st.job || "-");
      setText("robot", st.robot);
      setText("camera", st.camera);
      setText("queue", st.queue_length);
      setText("cycles_done", st.counters.cycles_done);
      setText("cycles_faulted", st.counters.cycles_faulted);
      setText("cycles_aborted", st.counters.cycles_aborted);
      showConfirm(st);
      showLast(st);
      document.body.dataset.connected = "yes";
    } catch (e) {
      document.body.dataset.connected = "no";
    }
  }

  async function act(cmd) {
    const body = new URLSearchParams();
    if (cmd === "start") body.set("job", $("job-select").value);
    const r = await fetch(`/action/${cmd}`, {method: "POST", credentials: "same-origin",
      headers: {"X-CSRF-Token": csrf}, body: body});
    const ans = await r.json();
    setText("action-result", `${cmd}: ` + (ans.ok ? "ok" : ans.error));
    poll();
  }

  for (const b of document.querySelectorAll("button[data-action]")) {
    b.addEventListener("click", (ev) => { ev.preventDefault(); act(b.dataset.action); });
  }
  poll();
  setInterval(poll, 250);
})();
