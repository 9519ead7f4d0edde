"""The five sources the ledger checks (their texts are in ``../shared/papers/``)."""

from __future__ import annotations

PRTT = "Sirikonda 2022 PRTT"
THESIS = "Sirikonda 2023 thesis"
DDPRT = "Belcour 2022 data-driven PRT"
NEURAL_WAVELET = "Raghavan 2023 neural wavelet"
LECTURE = "Ramamoorthi CSE168 lecture"

#: source -> full citation.
SOURCES = {
    PRTT: "Sirikonda, Aakash KT and Narayanan, PRTT: Precomputed Radiance Transfer Textures "
          "(arXiv 2203.12399, 2022)",
    THESIS: "Sirikonda, Extending PRT Framework for Lowly-Tessellated and Continuous Surfaces "
            "(MS thesis, IIIT Hyderabad, 2023)",
    DDPRT: "Belcour, Deliot, Barbier and Soler, A Data-Driven Paradigm for Precomputed Radiance "
           "Transfer (SIGGRAPH 2022)",
    NEURAL_WAVELET: "Raghavan, Wang, Ramamoorthi et al., Neural Free-Viewpoint Relighting for "
                    "Glossy Indirect Illumination (EGSR 2023)",
    LECTURE: "Ramamoorthi, CSE 168 lecture 16: Precomputed Rendering (UCSD, spring 2025)",
}
