"""Figure cpca: global PCA, VQ and CPCA of stored transfer at equal memory, with error maps.

The cases of ``table-cpca`` (:mod:`reproductions.table_cpca`: diffuse ``vertex`` on ``plants``
with a 32×32 ground, glossy ``sloan-matrix`` at 5 bands on ``bust``, under the sun; at smoke
both on ``plants``). Per case a memory budget is the stored bytes of a reference CPCA form
(K = 16 clusters × n′ = 4 vectors; smoke n′ = 2). Global PCA gets the most vectors and VQ the
most clusters whose stored bytes stay within it (:func:`equal_memory_forms`), so the three
forms cost the same memory to within one vector / one cluster. Columns: the uncompressed
method, PCA, VQ, CPCA, the Mitsuba path reference; under each render its error map against the
uncompressed render (the compression's own error, ×:data:`ERROR_SCALE` on the display image).

Every render is a runner cell: masked PSNR against the path reference, frame time and resident
bytes are stored result rows; the form's stored bytes and transfer RMSE come from its cached
artifact and the masked PSNR against the uncompressed render from the two display images, both
stored as measurement table ``figure-cpca``.
"""

from __future__ import annotations

from pathlib import Path

from prtbench.api.method import METHODS
from prtbench.bench import metrics
from prtbench.bench.job import Job
from prtbench.bench.reproduction import Figure, display_panels, provenance_line
from prtbench.io import imageio
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.compress import stored_bytes
from prtbench.transport.raytrace import geometry_mask
from reproductions import plots, shared
from reproductions.table_cpca import CASES, LIGHT, SMOKE_CASES, form_facts, form_overrides

#: The CPCA form whose stored bytes set each case's budget: (K, n′) per profile.
REFERENCE_FORM = {"smoke": (16, 2), "quick": (16, 4), "paper": (16, 4)}
FORMS = ("pca", "vq", "cpca")
#: Display-space error maps are |form − uncompressed| summed over RGB, times this.
ERROR_SCALE = 4.0
#: Measurement table: per run its form's facts and its PSNR against the uncompressed render.
TABLE = "figure-cpca"
#: Transfer dimension of each compressible method at n SH bands.
DIMENSION = {"vertex": lambda n: n * n, "sloan-matrix": lambda n: n**4}


def equal_memory_forms(*, n_signals: int, dimension: int, clusters: int, pca_vectors: int
                       ) -> dict[str, tuple[int, int]]:
    """(K, n′) of PCA, VQ and CPCA storing at most the bytes of CPCA K × n′.

    PCA (K = 1) takes the most vectors and VQ (n′ = 0) the most clusters whose
    :func:`~prtbench.transport.compress.cpca.stored_bytes` fit the budget.
    """

    def size(k: int, n: int) -> int:
        return stored_bytes(n_signals=n_signals, dimension=dimension, clusters=k,
                            pca_vectors=n)

    budget = size(clusters, pca_vectors)
    pca = max((n for n in range(1, dimension + 1) if size(1, n) <= budget), default=1)
    # VQ bytes grow by d floats per cluster on top of the N ids.
    vq = max(2, min(n_signals, (budget - 4 * n_signals) // (4 * dimension)))
    return {"pca": (1, pca), "vq": (int(vq), 0), "cpca": (clusters, pca_vectors)}


def _case_forms(case, profile: str) -> dict[str, tuple[int, int]]:
    _, method, scene, variant, params, base = case
    bands = METHODS.get(method).make_config(base, profile=profile).sh_bands
    n_signals = get_scene(scene, variant=variant, **params).n_vertices
    k, n = REFERENCE_FORM[profile]
    return equal_memory_forms(n_signals=n_signals, dimension=DIMENSION[method](bands),
                              clusters=k, pca_vectors=n)


class FigureCpca(Figure):
    name = "cpca"
    paper = ("Sloan, Hall, Hart and Snyder 2003, Clustered Principal Components for Precomputed "
             "Radiance Transfer (SIGGRAPH 2003), the comparison of VQ, PCA and CPCA at equal "
             "storage; Ramamoorthi, CSE 168 lecture, slides \"Local or Clustered PCA\"")
    title = "Figure cpca: PCA, VQ and CPCA of transfer at equal memory"
    substitutions = ("`bust` (the scanned snowden bust) stands in for Sloan 2003's scanned "
                     "models; `plants` is our procedural scene.",)

    def cells(self, profile: str) -> list[Job]:
        cells = []
        for case in SMOKE_CASES if profile == "smoke" else CASES:
            label, method, scene, variant, params, base = case
            common = dict(method=method, scene=scene, variant=variant, light=LIGHT, views=1,
                          scene_params=params)
            cells.append(Job(**common, overrides=dict(base),
                              label={"case": label, "form": "none", "K": 0, "n": -1}))
            for form, (k, n) in _case_forms(case, profile).items():
                cells.append(Job(**common, overrides={**base, **form_overrides(k, n)},
                                  label={"case": label, "form": form, "K": k, "n": n}))
        return cells

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        runs = shared.run_cells(self.cells(profile), profile=profile, results_path=results_path,
                                 progress=progress, tag=f"figure {self.name}")
        images, rows = {}, []
        for case in dict.fromkeys(r.cell.label["case"] for r in runs):
            mine = {r.cell.label["form"]: r for r in runs if r.cell.label["case"] == case}
            plain = mine["none"]
            view = plain.scene.trajectory.views[0]
            h, w = plain.image.shape[:2]
            mask = geometry_mask(plain.scene, view, w, h)
            shown = {f: imageio.display(r.image, exposure=r.scene.exposure)
                     for f, r in mine.items()}
            images[f"{case}/path"] = plain.reference
            for form, run in mine.items():
                images[f"{case}/{form}"] = shown[form]
                images[f"{case}/{form}/error"] = shared.error_image(
                    shown[form], shown["none"], scale=ERROR_SCALE)
                facts = form_facts(run.rows)
                rows.append({
                    "cell_run_id": run.run_id, "case": case, "form": form,
                    "K": run.cell.label["K"], "n": run.cell.label["n"],
                    "form_bytes": facts["form_bytes"], "transfer_bytes": facts["transfer_bytes"],
                    "transfer_rmse": facts["transfer_rmse"],
                    "psnr_masked_vs_uncompressed": (None if form == "none" else
                                                    metrics.compute_metrics(
                                                        shown[form], shown["none"], mask=mask,
                                                        names=["psnr"])["psnr_masked"]),
                    "substitution": run.scene.substitution or ""})
        measurements.record(TABLE, rows, results_path=results_path, run_id=run_id,
                            profile=profile, images=display_panels(images))
        return {run.run_id: dict(run.cell.label) for run in runs}

    def plot(self, stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        frame, images = stored.frame(), stored.images()
        table = stored.table(TABLE)
        extra = {r["cell_run_id"]: r for r in shared.records(table)}
        grid, captions, row_labels, caption_rows = [], [], [], []
        order = ("none", *FORMS)
        for case in dict.fromkeys(r["case"] for r in extra.values()):
            renders, errors, texts, error_texts = [], [], [], []
            for form in order:
                part = frame[(frame["label_case"] == case) & (frame["label_form"] == form)]
                run_id = str(part["run_id"].iloc[0])
                fact = extra[run_id]
                psnr = float(part["metric_psnr_masked"].mean())
                renders.append(images[f"{case}/{form}"])
                errors.append(images[f"{case}/{form}/error"] if form != "none" else None)
                texts.append(f"{fact['form_bytes'] / 2**20:.2f} MiB stored\n"
                             f"{psnr:.2f} dB vs path")
                error_texts.append("" if form == "none" else
                                   f"{fact['psnr_masked_vs_uncompressed']:.1f} dB vs none")
                caption_rows.append([
                    case, str(part["method"].iloc[0]), form, fact["K"] if fact["K"] else "—",
                    fact["n"] if fact["K"] else "—", int(fact["form_bytes"]),
                    int(part["memory_bytes"].iloc[0]),
                    float(fact["transfer_bytes"]) / float(fact["form_bytes"]),
                    float(fact["transfer_rmse"]), psnr,
                    "—" if form == "none" else fact["psnr_masked_vs_uncompressed"],
                    float(part["metric_flip_masked"].mean()), float(part["frame_ms"].median()),
                    run_id])
            renders.append(images[f"{case}/path"])
            errors.append(None)
            texts.append("")
            error_texts.append("")
            grid += [renders, errors]
            captions += [texts, error_texts]
            row_labels += [case, f"{case}\n|form − none| ×{ERROR_SCALE:g}"]
        spp = int(frame["reference_spp"].iloc[0])
        png = plots.panel_grid(
            reports_dir / f"figure-{self.name}.png", grid, row_labels=row_labels,
            captions=captions, title=self.title + f" ({profile} profile)",
            column_labels=["uncompressed", "global PCA (K = 1)", "VQ (n′ = 0)", "CPCA",
                           f"Mitsuba path\n{spp} spp"])
        subs = sorted({r["substitution"] for r in extra.values() if r["substitution"]})
        k, n = REFERENCE_FORM[profile]
        lines = [
            f"# {self.title}", "", f"Source: {self.paper}.", "",
            f"![figure {self.name}](figure-{self.name}.png)", "",
            f"Profile `{profile}`: panels {int(frame['width'].iloc[0])}×"
            f"{int(frame['height'].iloc[0])}, first trajectory view, light `{LIGHT}`. Equal "
            f"memory: each case's budget is the stored bytes of CPCA K={k} × n′={n}; global PCA "
            "takes the most vectors and VQ the most clusters within it. Error maps: the display "
            f"image's |form − uncompressed| summed over RGB, ×{ERROR_SCALE:g}.", "",
            provenance_line([frame, table], profile=profile), "",
            "\"PSNR vs path\" is the stored runner metric (masked, against the direct-only "
            "Mitsuba reference); \"PSNR vs none\" compares with the uncompressed render, i.e. "
            "the compression's own error, measured from the two display images after the runs "
            "and stored as measurement table `figure-cpca`, like the stored bytes and transfer "
            "RMSE of each cached form. Frame times on llvmpipe (a CPU rasteriser) compare only "
            "within this figure.", "",
            *shared.markdown_table(
                ["case", "method", "form", "K", "n′", "stored bytes", "resident bytes", "ratio",
                 "transfer RMSE", "PSNR masked vs path (dB)", "PSNR masked vs none (dB)",
                 "FLIP masked", "frame ms", "run id"], caption_rows),
        ]
        if subs:
            lines += ["", "Scene substitutions:", ""] + [f"- {s}" for s in subs]
        md = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, md]


FIGURE = FigureCpca()
