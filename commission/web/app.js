"use strict";
// ecs-commission page: polls /api/state, sends the page's requests, renews the hold.
const $ = (s) => document.querySelector(s);
let view = null, drive = 0, csv = "", livePlot = null, scopePlot = null;
const hold = { enable: false, dir: 0 };

function esc(s) {
  return String(s ?? "").replace(/[&<>"]/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;" }[c]));
}
async function api(path, body, raw) {
  const opt = body === undefined ? {} : {
    method: "POST",
    headers: raw ? {} : { "Content-Type": "application/json" },
    body: raw ? body : JSON.stringify(body),
  };
  const r = await fetch(path, opt);
  return r.json();
}
function say(el, text, good) {
  el.textContent = text;
  el.className = "msg " + (good ? "good" : "error");
}
const hex = (v, n) => "0x" + (v >>> 0).toString(16).toUpperCase().padStart(n, "0");

// Views.
document.querySelectorAll("nav button").forEach((b) => b.addEventListener("click", () => {
  document.querySelectorAll("nav button").forEach((x) => x.classList.toggle("on", x === b));
  document.querySelectorAll("main section").forEach((s) => (s.hidden = s.id !== "view-" + b.dataset.view));
  if (b.dataset.view === "plots") drawLive();
}));
$("#drive").addEventListener("change", (e) => (drive = Number(e.target.value)));

// Segment view and everything that follows the state.
function render() {
  $("#status").textContent = view.status + " on " + view.iface;
  const sel = $("#drive");
  if (sel.options.length !== view.drives.length) {
    sel.innerHTML = view.drives.map((d) => `<option value="${d.position}">${d.position}: ${esc(d.name)}</option>`).join("");
    sel.value = String(drive);
  }
  $("#segment tbody").innerHTML = view.drives.map((d) => `<tr>
    <td>${d.position}</td><td>${hex(d.address, 4)}${d.alias ? " (alias " + d.alias + ")" : ""}</td>
    <td>${esc(d.name)}</td><td>${d.identity.map((v) => hex(v, 8)).join(" / ")}</td><td>${esc(d.version)}</td>
    <td>${esc(d.esm)}</td><td>${hex(d.al_code, 4)} ${esc(d.al_text)}</td>
    <td>${esc(d.cia402)} (${hex(d.statusword, 4)})</td><td>${d.actual_position}</td>
    ${d.fault ? `<td class="fault">${esc(d.fault)}</td>` : "<td>none</td>"}<td>${esc(d.led)}</td></tr>`).join("");
  const d = view.drives[drive];
  if (d) {
    $("#jog-state").textContent = d.cia402;
    $("#jog-pos").textContent = d.actual_position;
  }
  $("#jog-hold").textContent = view.hold[0] ? "enabled, jog " + view.hold[1] : "off";
  $("#emcy-list tbody").innerHTML = view.emergencies.map((e) =>
    `<tr><td>${e.drive}</td><td>${e.time_s.toFixed(2)}</td><td>${e.code}</td><td>${esc(e.text)}</td></tr>`).join("");
  const u = view.update;
  if (u.state) {
    $("#update-progress").max = Math.max(u.total, 1);
    $("#update-progress").value = u.state === "done" ? u.total : u.sent;
    say($("#update-answer"), u.answer, u.state !== "failed");
  }
  if (!$("#view-plots").hidden) drawLive();
}
async function poll() {
  try {
    view = await api("/api/state");
    render();
  } catch (e) {
    $("#status").textContent = "no answer from ecs-commission";
  }
}
setInterval(poll, 200);
poll();

// Live plots of process data.
function drawLive() {
  if (!view || !view.live.length) return;
  const t = view.live.map((s) => s[0]);
  const pick = [...document.querySelectorAll("#live-choice input:checked")].map((c) => c.value);
  const series = [{}], data = [t];
  for (const p of pick) {
    series.push({ label: p === "pos" ? "0x6064 position [inc]" : "0x6041 statusword", stroke: p === "pos" ? "#1f77b4" : "#d62728", scale: p });
    data.push(view.live.map((s) => (s[1][drive] || [0, 0])[p === "pos" ? 0 : 1]));
  }
  const key = pick.join(",");
  if (!livePlot || livePlot.key !== key) {
    if (livePlot) livePlot.destroy();
    livePlot = new uPlot({ width: 900, height: 320, series, scales: { x: { time: false } },
      axes: [{ label: "s since the tool started" }, ...pick.map((p, i) => ({ scale: p, side: i ? 1 : 3, size: 70 }))] }, data, $("#live-plot"));
    livePlot.key = key;
  } else {
    livePlot.setData(data);
  }
}
document.querySelectorAll("#live-choice input").forEach((c) => c.addEventListener("change", drawLive));

// Dictionary.
let objects = [];
function listObjects() {
  const f = $("#dict-filter").value.toLowerCase();
  $("#dict-objects").innerHTML = objects
    .filter((o) => !f || hex(o.index, 4).toLowerCase().includes(f) || o.name.toLowerCase().includes(f))
    .map((o) => `<li data-index="${o.index}">${hex(o.index, 4)} ${esc(o.name)}</li>`).join("");
}
$("#dict-filter").addEventListener("input", listObjects);
$("#dict-load").addEventListener("click", async () => {
  say($("#dict-msg"), "reading the dictionary…", true);
  const r = await api(`/api/objects?drive=${drive}`);
  if (r.error) return say($("#dict-msg"), r.error);
  objects = r.ok;
  listObjects();
  say($("#dict-msg"), `${objects.length} objects`, true);
});
$("#dict-objects").addEventListener("click", (e) => {
  const li = e.target.closest("li");
  if (li) openObject(Number(li.dataset.index));
});
$("#dict-open").addEventListener("click", () => openObject(Number($("#dict-index").value)));
async function openObject(index) {
  const r = await api(`/api/objects?drive=${drive}&index=${index}`);
  if (r.error) return say($("#dict-msg"), r.error);
  const o = r.ok.object;
  $("#dict-title").textContent = `${hex(o.index, 4)} ${o.name}`;
  $("#dict-entries tbody").innerHTML = r.ok.entries.map(({ entry: e, value, error }) => {
    const w = (e.access & 0x38) !== 0;
    return `<tr><td>${e.sub}</td><td>${esc(e.name)}</td><td>${e.type_name}</td><td>${esc(e.access_text)}</td>
      <td>${esc(e.default)}</td><td>${esc(e.min)}</td><td>${esc(e.max)}</td>
      <td>${w ? `<input class="edit" data-index="${o.index}" data-sub="${e.sub}" data-type="${e.data_type}" value="${esc(value ?? "")}">`
              : `<span class="value">${esc(value ?? error)}</span>`}</td>
      <td>${w ? `<button class="write" data-sub="${e.sub}">Write</button>` : ""}</td></tr>`;
  }).join("");
}
$("#dict-entries").addEventListener("click", async (e) => {
  if (!e.target.classList.contains("write")) return;
  const input = e.target.closest("tr").querySelector("input.edit");
  const text = input.value.trim();
  // Validation before the drive: a number for the numeric types.
  const numeric = ![8, 9, 10].includes(Number(input.dataset.type));
  if (numeric && !/^(-?\d+|0x[0-9a-f]+)$/i.test(text)) {
    return say($("#dict-msg"), `'${text}' is not a whole number`);
  }
  const index = Number(input.dataset.index), sub = Number(input.dataset.sub);
  const r = await api("/api/write", { drive, index, sub, value: text });
  if (r.error) {
    say($("#dict-msg"), `${hex(index, 4)}:${sub}: the drive refused: ${r.error}`);
    openObject(index);
  } else {
    input.value = r.ok;
    say($("#dict-msg"), `${hex(index, 4)}:${sub} = ${r.ok} (read back)`, true);
  }
});
for (const [id, load] of [["#dict-save", false], ["#dict-restore", true]]) {
  $(id).addEventListener("click", async () => {
    const r = await api("/api/store", { drive, load });
    r.error ? say($("#dict-msg"), r.error) : say($("#dict-msg"), r.ok, true);
  });
}

// Scope.
$("#scope-run").addEventListener("click", async () => {
  say($("#scope-msg"), "capturing…", true);
  const r = await api("/api/scope", {
    drive,
    channels: $("#scope-channels").value.split(",").map((s) => s.trim()).filter((s) => s),
    condition: $("#scope-cond").value,
    level: Number($("#scope-level").value),
    pretrigger: Number($("#scope-pre").value),
    divisor: Number($("#scope-div").value),
    servo_rate: $("#scope-servo").checked,
  });
  if (r.error) return say($("#scope-msg"), r.error);
  const rec = r.ok;
  csv = rec.csv;
  $("#scope-csv").disabled = false;
  const data = [rec.time_ms, ...rec.labels.map((_, c) => rec.rows.map((row) => row[c]))];
  const colours = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf"];
  const series = [{ label: "ms from the trigger" }, ...rec.labels.map((l, c) => ({ label: l, stroke: colours[c % 8], scale: "s" + c }))];
  const axes = [{ label: "ms from the trigger" }, ...rec.labels.map((_, c) => ({ scale: "s" + c, side: c % 2 ? 1 : 3, show: c < 2, size: 70 }))];
  if (scopePlot) scopePlot.destroy();
  scopePlot = new uPlot({ width: 900, height: 360, series, axes, scales: { x: { time: false } }, cursor: { drag: { x: true, y: false } } }, data, $("#scope-plot"));
  say($("#scope-msg"), `${rec.rows.length} samples${rec.forced ? " (no trigger: forced)" : ""}; drag to zoom, double-click to zoom out`, true);
});
$("#scope-csv").addEventListener("click", () => {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([csv], { type: "text/csv" }));
  a.download = "scope.csv";
  a.click();
});

// Faults.
$("#faults-read").addEventListener("click", async () => {
  const r = await api(`/api/history?drive=${drive}`);
  if (r.error) return;
  $("#faults-history tbody").innerHTML = r.ok.map((m) =>
    `<tr><td>${m.time_ms}</td><td>${m.code}</td><td>${m.severity}</td><td>${esc(m.text)}</td></tr>`).join("") ||
    "<tr><td colspan=4>no messages</td></tr>";
});

// Enable and jog: the hold is renewed every 100 ms while "Enable" is on.
let mode = 3;
function sendHold() {
  return api("/api/hold", { drive, enable: hold.enable, dir: hold.dir, speed: Number($("#jog-speed").value) || 0, mode });
}
setInterval(() => { if (hold.enable) sendHold(); }, 100);
$("#enable").addEventListener("change", (e) => {
  hold.enable = e.target.checked;
  hold.dir = 0;
  mode = 3;
  sendHold();
});
for (const [id, dir] of [["#jog-minus", -1], ["#jog-plus", 1]]) {
  const b = $(id);
  b.addEventListener("pointerdown", () => { if (hold.enable) { hold.dir = dir; mode = 3; sendHold(); } });
  for (const ev of ["pointerup", "pointerleave", "pointercancel"]) {
    b.addEventListener(ev, () => { if (hold.dir) { hold.dir = 0; sendHold(); } });
  }
}
window.addEventListener("blur", () => { if (hold.dir) { hold.dir = 0; sendHold(); } });

// Tuning.
for (const [id, servo] of [["#tune-current", false], ["#tune-servo", true]]) {
  $(id).addEventListener("click", async () => {
    if (servo) { mode = 1; if (hold.enable) await sendHold(); }
    const r = await api("/api/tune", { drive, servo });
    r.error ? say($("#tune-msg"), "the drive refused: " + r.error) : say($("#tune-msg"), "tune started", true);
  });
}
$("#tune-results").addEventListener("click", async () => {
  const r = await api("/api/tune", { drive });
  if (r.error) return say($("#tune-msg"), r.error);
  $("#tune-out").textContent = Object.entries(r.ok).map(([k, v]) => `${k}: ${v}`).join("\n");
});

// Firmware update.
$("#update-run").addEventListener("click", async () => {
  const f = $("#update-file").files[0];
  if (!f) return say($("#update-answer"), "choose an .efw file first");
  say($("#update-answer"), "sending…", true);
  const r = await api(`/api/update?drive=${drive}`, await f.arrayBuffer(), true);
  if (r.error) say($("#update-answer"), r.error);
});
