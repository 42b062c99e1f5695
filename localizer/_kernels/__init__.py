"""The localizer's compiled kernels (numba, :data:`localizer._jit.jit`).

The package is private: the public API is :mod:`localizer`. Inside it every kernel has a
public name, so that the Python modules of :mod:`localizer` import them without reaching
into another module's private names. Conventions of every kernel: pixel coordinates
follow :mod:`localizer.model.camera` (pixel centres at integers, ``x`` = column, ``y`` = row),
images are ``(H, W)`` uint8 C-contiguous arrays, lengths on the target are metres, angles
radians. The named tuples and enums passed in and out are in :mod:`.records`.

Modules, in pipeline order:

* :mod:`.scan` -- thresholding, run-length coding and the triple search of scan lines;
* :mod:`.search` -- the whole compiled search (coarse scan, cheap tests, fine search);
* :mod:`.fine` -- the fine search of one coarse hit;
* :mod:`.verify` -- pattern verification of a stack, rough bar ends;
* :mod:`.half_pixel` -- the thesis's half-pixel edges;
* :mod:`.subpixel` -- gradient-centroid subpixel edges;
* :mod:`.blur` -- the sampled Gaussian blur of a box-pixel step (shared model);
* :mod:`.clipped` -- clipped (saturated), blurred-step edge fits;
* :mod:`.target_test` -- whether measured edges still make a target;
* :mod:`.projection` -- where the target's edges and lines image;
* :mod:`.exact_pose` -- the perspective-exact pose fit;
* :mod:`.measure` -- subpixel edges, target test and exact pose fused in one call;
* :mod:`.photometric` -- the whole-target photometric refinement;
* :mod:`.area` -- the area-averaged levels of a large frame (:mod:`localizer.image.pyramid`).

and :mod:`.arrays`, the element-wise copies the kernels use instead of assigning an array to
a slice (smaller compiled code: its docstring says why).
"""
