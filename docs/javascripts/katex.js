// Typesets the maths that pymdownx.arithmatex marks (\( ... \) inline, \[ ... \] displayed)
// with the copy of KaTeX served from this site (docs/vendor/katex), on every page load and
// every page the theme's instant navigation swaps in.
document$.subscribe(({ body }) => {
  for (const element of body.querySelectorAll(".arithmatex")) {
    renderMathInElement(element, {
      delimiters: [
        { left: "\\(", right: "\\)", display: false },
        { left: "\\[", right: "\\]", display: true },
      ],
      throwOnError: false,
    });
  }
});
