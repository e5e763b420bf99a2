// rvdiag fleet dashboard: the token kept for this tab (sessionStorage), acknowledge / maintenance forms, and the
// Plotly figures whose JSON the server wrote into the page.  No other script, no network beyond this server's API.
(function () {
  "use strict";
  var KEY = "rvdiag-token";
  var body = document.body;
  var api = body.getAttribute("data-api");
  var readToken = body.getAttribute("data-read-token") === "yes";

  function token() { try { return sessionStorage.getItem(KEY) || ""; } catch (e) { return ""; } }

  function setToken(value) {
    try {
      if (value) { sessionStorage.setItem(KEY, value); } else { sessionStorage.removeItem(KEY); }
    } catch (e) { /* storage disabled: the token lasts until the page is left */ }
    if (readToken) {  // reads need a token: send it as a cookie for this tab's page loads (never used for writes)
      document.cookie = "rvdiag_token=" + (value ? encodeURIComponent(value) : "") + "; path=/; SameSite=Strict" +
        (value ? "" : "; Max-Age=0");
    }
    showToken();
  }

  function showToken() {
    var state = document.getElementById("token-state");
    var forget = document.getElementById("token-forget");
    if (!state) { return; }
    var have = !!token();
    state.textContent = have ? "token kept for this tab" : "no token: reading only";
    if (forget) { forget.hidden = !have; }
  }

  function jointUrl(joint, what) {
    return api + "/joints/" + joint.split("/").map(encodeURIComponent).join("/") + "/" + what;
  }

  function wireToken() {
    var form = document.getElementById("token-form");
    if (!form) { return; }
    form.addEventListener("submit", function (ev) {
      ev.preventDefault();
      var input = document.getElementById("token-input");
      setToken(input.value.trim());
      input.value = "";
    });
    document.getElementById("token-forget").addEventListener("click", function () { setToken(""); });
    showToken();
  }

  function wireWrites() {
    var forms = document.querySelectorAll("form.write");
    Array.prototype.forEach.call(forms, function (form) {
      form.addEventListener("submit", function (ev) {
        ev.preventDefault();
        var out = form.querySelector(".result");
        var note = form.querySelector(".note").value.trim();
        var tok = token();
        out.className = "result";
        if (!tok) {
          out.className = "result fail";
          out.textContent = "enter a read-write token at the top first";
          return;
        }
        var button = form.querySelector("button");
        button.disabled = true;
        fetch(jointUrl(form.getAttribute("data-joint"), form.getAttribute("data-action")), {
          method: "POST",
          headers: { "Authorization": "Bearer " + tok, "Content-Type": "application/json" },
          body: JSON.stringify({ note: note }),
          credentials: "same-origin"
        }).then(function (resp) {
          return resp.json().then(function (data) { return { ok: resp.ok, data: data }; });
        }).then(function (r) {
          if (r.ok) {
            out.className = "result ok";
            out.textContent = "done";
            window.setTimeout(function () { window.location.reload(); }, 300);
          } else {
            out.className = "result fail";
            out.textContent = (r.data && r.data.error) || "refused";
            button.disabled = false;
          }
        }).catch(function (e) {
          out.className = "result fail";
          out.textContent = "no answer from the server: " + e;
          button.disabled = false;
        });
      });
    });
  }

  function drawPlots() {
    if (typeof window.Plotly === "undefined") { return; }
    var specs = document.querySelectorAll('script[type="application/json"][data-plot]');
    Array.prototype.forEach.call(specs, function (spec) {
      var target = document.getElementById(spec.getAttribute("data-plot"));
      if (!target) { return; }
      var fig = JSON.parse(spec.textContent);
      window.Plotly.newPlot(target, fig.data, fig.layout, { displaylogo: false, responsive: true })
        .then(function () { target.setAttribute("data-drawn", "yes"); });
    });
  }

  function start() { wireToken(); if (api) { wireWrites(); } drawPlots(); }
  if (document.readyState === "loading") { document.addEventListener("DOMContentLoaded", start); } else { start(); }
})();
