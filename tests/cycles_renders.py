"""Renders of one bpy scene by Ember and by Cycles, and the region test that compares them:
the means over the image and its four quadrants, Ember's within a tolerance of Cycles' plus
the Sidak-corrected noise band of independent seeds (a t-test)."""
from __future__ import annotations

import numpy as np
from scipy import stats as st

import bpy

from ember.engine.blender import final
from stats import sidak_alpha


class _Film:
    film = None

    def on_progress(self, layer, progress):
        self.film = progress.film


def ember_film(sc, integrator: str, samples: int, seed: int):
    """The film of an F12 render with Ember."""
    sc.render.engine = "EMBER"
    sc.ember.integrator, sc.ember.samples, sc.ember.seed = integrator, samples, seed
    grab = _Film()
    final.listeners.append(grab)
    try:
        bpy.ops.render.render()
    finally:
        final.listeners.remove(grab)
    return grab.film


def ember_image(sc, integrator: str, samples: int, seed: int) -> np.ndarray:
    """(H, W, 3) the film's mean of an F12 render with Ember."""
    film = ember_film(sc, integrator, samples, seed)
    return film.mean().reshape(sc.render.resolution_y, sc.render.resolution_x, 3)


def rgba_ember(sc, samples: int, seed: int, integrator: str = "PATH") -> np.ndarray:
    """(H, W, 4) Ember's F12 render with its film's alpha."""
    film = ember_film(sc, integrator, samples, seed)
    return film.image().reshape(sc.render.resolution_y, sc.render.resolution_x, 4)


def rgba_cycles(sc, samples: int, seed: int, path) -> np.ndarray:
    """(H, W, 4) Cycles' render with its alpha, through an RGBA EXR at `path` (top row first)."""
    sc.render.engine = "CYCLES"
    sc.cycles.samples, sc.cycles.seed = samples, seed
    sc.render.filepath = str(path)
    sc.render.image_settings.file_format = "OPEN_EXR"
    sc.render.image_settings.color_mode = "RGBA"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(path))
    h, w = sc.render.resolution_y, sc.render.resolution_x
    out = np.array(img.pixels[:]).reshape(h, w, 4)[::-1]
    bpy.data.images.remove(img)
    return out


def cycles_image(sc, samples: int, seed: int, path) -> np.ndarray:
    """(H, W, 3) Cycles' render, through an EXR at `path` (top row first)."""
    return rgba_cycles(sc, samples, seed, path)[:, :, :3]


def region_means(images) -> np.ndarray:
    """(K, 5) means over each image and its four quadrants (all channels)."""
    h, w = np.shape(images[0])[:2]
    quads = [(slice(None), slice(None)), (slice(0, h // 2), slice(0, w // 2)), (slice(0, h // 2), slice(w // 2, None)),
             (slice(h // 2, None), slice(0, w // 2)), (slice(h // 2, None), slice(w // 2, None))]
    return np.array([[img[q].mean() for q in quads] for img in images])


def agree(ember_images, cycles_images, n_tests: int, tol: float) -> np.ndarray:
    """Assert the region means agree within tol plus the noise band (family-wise level 0.01
    over n_tests such comparisons); returns Ember / Cycles per region."""
    e, c = region_means(ember_images), region_means(cycles_images)
    diff = e.mean(axis=0) - c.mean(axis=0)
    se = np.sqrt(e.var(axis=0, ddof=1) / len(e) + c.var(axis=0, ddof=1) / len(c))
    t = st.t.ppf(1 - sidak_alpha(0.01, n_tests * e.shape[1]) / 2, min(len(e), len(c)) - 1)
    ok = np.abs(diff) <= tol * np.abs(c.mean(axis=0)) + t * se
    assert ok.all(), f"Ember / Cycles region means {e.mean(0) / c.mean(0)}, noise band {t * se / c.mean(0)}"
    return e.mean(axis=0) / c.mean(axis=0)
