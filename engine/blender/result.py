"""Film -> Blender render result.

The core's film is the full frame, rows from the top, (H, W, 4) float32. Blender's result
is different in two ways (blender.md section 6, items 1-3):
- `rect` rows run bottom-up, flattened, float32 only (`foreach_set`; a float64 array raises);
- with render border on, the result is border-sized and `begin_result` takes coordinates
  relative to the border's own origin, so we begin (0, 0, bw, bh) and write the crop.

Blender's border in pixels (checked against bpy 5.0.1 render results): with the frame
W x H (resolution percentage applied) and border fractions (min_x, max_x, min_y, max_y),
x0 = int(min_x * W), x1 = int(max_x * W), likewise y from the bottom, computed in float32
and truncated, as Blender's C code does.
"""
from __future__ import annotations

import numpy as np


def blender_border(render, width: int, height: int) -> tuple:
    """Blender's render border as (x0, y0, x1, y1) in pixels, half-open, TOP-left origin
    (the convention of engine.scene.Settings.border). The whole frame if border is off.

    render: bpy.types.RenderSettings (use_border, border_min_x, ...), or anything with
    those attributes.
    """
    if not getattr(render, "use_border", False):
        return (0, 0, width, height)
    f32 = np.float32
    x0 = int(f32(render.border_min_x) * f32(width))
    x1 = int(f32(render.border_max_x) * f32(width))
    yb0 = int(f32(render.border_min_y) * f32(height))  # from the bottom
    yb1 = int(f32(render.border_max_y) * f32(height))
    x0, x1 = max(0, min(x0, width)), max(0, min(x1, width))
    yb0, yb1 = max(0, min(yb0, height)), max(0, min(yb1, height))
    return (x0, height - yb1, x1, height - yb0)


def rect_from_image(image: np.ndarray, border: tuple) -> np.ndarray:
    """Full-frame top-down (H, W, 4) image -> flat float32 array for `rect.foreach_set`:
    the border crop, rows bottom-up."""
    x0, y0, x1, y1 = border
    crop = image[y0:y1, x0:x1, :4] if image.ndim == 3 else image[y0:y1, x0:x1]
    return np.ascontiguousarray(crop[::-1], dtype=np.float32).reshape(-1)


def image_from_rect(flat: np.ndarray, width: int, height: int) -> np.ndarray:
    """Inverse of rect_from_image for a result of width x height: (h, w, 4) top-down."""
    return np.asarray(flat, np.float32).reshape(height, width, 4)[::-1]


class ResultWriter:
    """One render result for one view layer, written progressively.

    begin_result happens in the constructor; call write(image) as often as wanted and
    end() exactly once (it writes zeros first if nothing was ever written: an unwritten
    cropped result is what made Blender crash on save).
    """

    def __init__(self, engine, layer: str, width: int, height: int, border: tuple):
        self.engine = engine
        self.layer = layer
        self.width, self.height = width, height
        self.border = tuple(int(v) for v in border)
        x0, y0, x1, y1 = self.border
        self.size = (x1 - x0, y1 - y0)
        if self.size[0] <= 0 or self.size[1] <= 0:
            raise RuntimeError(f"empty render border {self.border}")
        # Coordinates relative to the border origin: (0, 0) is its bottom-left pixel.
        self.result = engine.begin_result(0, 0, self.size[0], self.size[1], layer=layer)
        if self.result is None:
            raise RuntimeError(f"Blender returned no render result for layer {layer!r}")
        res_size = (getattr(self.result, "resolution_x", self.size[0]),
                    getattr(self.result, "resolution_y", self.size[1]))
        if tuple(res_size) != self.size:
            engine.end_result(self.result, cancel=True)
            self.result = None
            raise RuntimeError(f"render result is {res_size[0]}x{res_size[1]}, "
                               f"expected {self.size[0]}x{self.size[1]} (border {self.border})")
        self._combined = self.result.layers[0].passes["Combined"]
        self.writes = 0
        self.fields = {}  # stamp(): header metadata

    def write(self, image: np.ndarray) -> None:
        """image: (height, width, 4) full frame, row 0 = top."""
        if image.shape[:2] != (self.height, self.width):
            raise ValueError(f"film is {image.shape[1]}x{image.shape[0]}, "
                             f"frame is {self.width}x{self.height}")
        self._combined.rect.foreach_set(rect_from_image(image, self.border))
        self.engine.update_result(self.result)
        self.writes += 1

    def write_passes(self, film) -> list:
        """Every pass the film keeps for the view layer (engine/passes.py) into the result's
        passes of the same name (Blender created them from update_render_passes). Returns the
        names it could not find in the result."""
        missing = []
        layer = self.result.layers[0]
        for name in film.passes_wanted:
            target = layer.passes.get(name)
            if target is None:
                missing.append(name)
                continue
            target.rect.foreach_set(rect_from_image(film.pass_image(name), self.border))
        self.engine.update_result(self.result)
        return missing

    def stamp(self, fields: dict) -> None:
        """Metadata for the image header (multilayer EXR, stamp): field -> text. Written at
        end() on the engine's whole result (as Cycles does: a layer result's stamp is not kept)."""
        self.fields = dict(fields)

    def end(self) -> None:
        if self.result is None:
            return
        try:
            if self.writes == 0:
                self.write(np.zeros((self.height, self.width, 4), np.float32))
        finally:
            self.engine.end_result(self.result)
            self.result = None
        whole = self.engine.get_result() if self.fields and hasattr(self.engine, "get_result") else None
        for key, value in self.fields.items() if whole is not None else ():
            whole.stamp_data_add_field(key, str(value))
