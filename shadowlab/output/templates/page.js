// Flip in place (no network): every .cfg figure carries its images per view in data-* attributes
// and its scene section the truth's; the view buttons switch a section's figures between error
// map, shaded image and visibility, and holding the pointer on a figure (or pressing t while over
// it) shows the truth's image of that view in its place, insets included.
(function () {
  function show(fig, src) {
    if (!src) return;
    var img = fig.querySelector(".frame img");
    if (img) img.src = src;
    fig.querySelectorAll(".inset").forEach(function (d) { d.style.backgroundImage = "url(" + JSON.stringify(src) + ")"; });
  }
  function view(section) { return section.getAttribute("data-view") || "error"; }
  // a figure without the section's view (no signed map, no footprint) shows its shaded image, dimmed
  function own(fig) {
    var src = fig.getAttribute("data-" + view(fig.closest("[data-view]")));
    fig.classList.toggle("na", !src);
    return src || fig.getAttribute("data-shaded");
  }
  function truth(fig) {
    var s = fig.closest("[data-view]"), v = view(s);
    return s.getAttribute("data-truth-" + (v === "shaded" ? "shaded" : "visibility"));
  }
  document.querySelectorAll("[data-view]").forEach(function (section) {
    section.querySelectorAll(".views button").forEach(function (b) {
      b.addEventListener("click", function () {
        section.setAttribute("data-view", b.getAttribute("data-show"));
        section.querySelectorAll(".views button").forEach(function (o) { o.classList.toggle("on", o === b); });
        section.querySelectorAll(".cfg[data-error]").forEach(function (f) { show(f, own(f)); });
      });
    });
    section.querySelectorAll(".cfg[data-error]").forEach(function (fig) {
      fig.addEventListener("pointerdown", function () { show(fig, truth(fig)); });
      ["pointerup", "pointerleave"].forEach(function (e) { fig.addEventListener(e, function () { show(fig, own(fig)); }); });
    });
  });
  var hovered = null;
  document.addEventListener("pointerover", function (e) { hovered = e.target.closest && e.target.closest(".cfg[data-error]"); });
  document.addEventListener("keydown", function (e) { if (e.key === "t" && hovered) show(hovered, truth(hovered)); });
  document.addEventListener("keyup", function (e) { if (e.key === "t" && hovered) show(hovered, own(hovered)); });
})();
