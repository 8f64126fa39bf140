/* robotcal report, first script: record every script error, failed resource and console error/warning
 * in window.robotcalErrors, so that the self-check (check.js) can show them and the browser test can
 * read them from the DOM. */
(function () {
  "use strict";
  var errors = (window.robotcalErrors = []);
  window.addEventListener("error", function (event) {
    if (event.target && event.target !== window && event.target.tagName) {
      errors.push("failed to load <" + event.target.tagName.toLowerCase() + ">");
    } else {
      errors.push(String(event.message || event.error || "script error"));
    }
  }, true);
  window.addEventListener("unhandledrejection", function (event) {
    errors.push("unhandled rejection: " + String(event.reason));
  });
  document.addEventListener("securitypolicyviolation", function (event) {
    errors.push("blocked by the content security policy: " + event.blockedURI);
  });
  ["error", "warn"].forEach(function (level) {
    var original = console[level];
    console[level] = function () {
      errors.push(level + ": " + Array.prototype.map.call(arguments, String).join(" "));
      return original.apply(console, arguments);
    };
  });
})();
