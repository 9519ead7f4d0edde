// Draws the scene page's Pareto plots (plotly.js, shipped next to the pages) and opens a
// configuration's images in the comparison when its point is clicked.
(function () {
  "use strict";
  document.querySelectorAll("script.pareto-data").forEach((source) => {
    const target = document.getElementById(source.dataset.target);
    const figure = JSON.parse(source.textContent);
    Plotly.newPlot(target, figure.data, figure.layout, { displaylogo: false, responsive: true })
      .then((plot) => {
        plot.on("plotly_click", (event) => {
          const point = event.points && event.points[0];
          if (point && point.customdata && window.prtbenchCompare) {
            window.prtbenchCompare.select(point.customdata);
            history.replaceState(null, "", `#${point.customdata}`);
          }
        });
        target.dataset.drawn = "true";
      });
  });
})();
