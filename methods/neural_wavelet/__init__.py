"""Neural wavelet transport (Raghavan et al. 2023, DESIGN.md §17): glossy indirect light.

T(x, j, ωo) = f_θ(F(x, j), SH(ωr), n, kd, ks, s) with the CP-factored feature field
F(x, j) = Mᵀ (H(x) ⊙ W(j)); the indirect radiance of a pixel is Σ_{j ∈ top-k(L)} L_j T(x, j, ωo).
One noun per module:

* :mod:`.hashgrid`: the 3-D multiresolution hash grid H (pure torch);
* :mod:`.model`: the feature field (hash grid or vertex features), W, M and the MLP f_θ;
* :mod:`.data`: training images from Mitsuba (indirect only) with GL G-buffers, lights, views;
* :mod:`.train`: the training loop (selected wavelets, adaptive pixel sampling) and its cache;
* :mod:`.gbuffer`: the GL G-buffer pass shared by training data and the renderer.

Importing this package imports nothing heavy; torch, moderngl and mitsuba load inside the
modules that need them (``prtbench list`` stays instant).
"""
