/* robotcal report, last script: once the page has loaded, check that every figure decoded and every
 * canvas drew something, then set the body's data-status to "ok" (or "error") and list any recorded errors
 * in #rc-errors. The browser test reads these attributes from the DOM. Also opens the folded long tables
 * before printing. */
(function () {
  "use strict";
  function finish() {
    var errors = window.robotcalErrors || ["errors.js did not run"];
    var images = document.images, imagesOk = 0;
    for (var i = 0; i < images.length; i++) {
      var good = images[i].complete && images[i].naturalWidth > 0;
      images[i].dataset.loaded = good ? "1" : "0";
      if (good) imagesOk++; else errors.push("figure did not render: " + (images[i].alt || "image " + i));
    }
    var canvases = document.querySelectorAll("canvas"), canvasesOk = 0;
    for (var j = 0; j < canvases.length; j++) {
      if (canvases[j].dataset.rendered === "1" && Number(canvases[j].dataset.ink) > 0) canvasesOk++;
      else errors.push("3-D view did not draw: canvas " + j);
    }
    var body = document.body;
    body.dataset.figures = String(images.length);
    body.dataset.figuresOk = String(imagesOk);
    body.dataset.canvases = String(canvases.length);
    body.dataset.canvasesOk = String(canvasesOk);
    var box = document.getElementById("rc-errors");
    if (errors.length) {
      box.textContent = "This page had problems while rendering:\n" + errors.join("\n");
      box.hidden = false;
    }
    body.dataset.errors = String(errors.length);
    body.dataset.status = errors.length ? "error" : "ok";
  }
  // long tables are folded (<details class="rc-fold">): a printed page shows them whole
  window.addEventListener("beforeprint", function () {
    var folds = document.querySelectorAll("details.rc-fold");
    for (var k = 0; k < folds.length; k++) folds[k].open = true;
  });
  if (document.readyState === "complete") finish();
  else window.addEventListener("load", finish);
})();
