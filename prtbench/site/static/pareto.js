// Draws the scene page's Pareto plots (plotly.js, shipped next to the pages, one per protocol
// panel) and opens a configuration's images in the comparison when its point is clicked (its
// table row when it has no cached images).
(function () {
  "use strict";
  document.querySelectorAll("script.pareto-data").forEach((source) => {
    const target = document.getElementById(source.dataset.target);
    const figure = JSON.parse(source.textContent);
    Plotly.newPlot(target, figure.data, figure.layout, { displaylogo: false, responsive: true })
      .then((plot) => {
        plot.on("plotly_click", (event) => {
          const point = event.points && event.points[0];
          if (!point || !point.customdata) return;
          const shown = window.prtbenchCompare && window.prtbenchCompare.select(point.customdata);
          if (!shown) {
            const row = document.getElementById(point.customdata);
            if (row) row.scrollIntoView({ block: "center" });
          }
          history.replaceState(null, "", `#${point.customdata}`);
        });
        target.dataset.drawn = "true";
      });
  });
})();
