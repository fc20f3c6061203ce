"""Overlay text: a glyph atlas rendered once with PIL, drawn as one instanced quad per glyph.

A monospaced font makes layout a multiplication; the atlas keeps one solid white cell so
the translucent panels behind the text use the same shader and the same draw call.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .geometry import quad_strip
from .shaders import TEXT_FS, TEXT_VS

FIRST, LAST = 32, 126  # printable ASCII; anything else is drawn as "?"
COLUMNS = 16
MONO_FONTS = ("/usr/share/fonts/truetype/dejavu/DejaVuSansMono.ttf",
              "/usr/share/fonts/TTF/DejaVuSansMono.ttf", "/Library/Fonts/Menlo.ttc",
              "C:/Windows/Fonts/consola.ttf")
PANEL = "\x7f"  # the solid cell (DEL is not printable, so it never collides with text)


def _load_font(size: int):
    from PIL import ImageFont

    for path in MONO_FONTS:
        if Path(path).exists():
            return ImageFont.truetype(path, size)
    return ImageFont.load_default(size=size)  # Pillow's bundled font: proportional but present


class FontAtlas:
    """Cell-sized glyphs of ASCII 32..126 plus a solid cell, as one 8-bit image."""

    def __init__(self, size: int = 15) -> None:
        from PIL import Image, ImageDraw

        font = _load_font(size)
        ascent, descent = font.getmetrics()
        self.cell_w = int(np.ceil(max(font.getlength(chr(c)) for c in range(FIRST, LAST + 1))))
        self.cell_h = ascent + descent
        count = LAST - FIRST + 2
        rows = -(-count // COLUMNS)
        self.image = Image.new("L", (COLUMNS * self.cell_w, rows * self.cell_h), 0)
        draw = ImageDraw.Draw(self.image)
        for i, c in enumerate(range(FIRST, LAST + 1)):
            draw.text(self._origin(i), chr(c), font=font, fill=255)
        x, y = self._origin(count - 1)
        draw.rectangle([x, y, x + self.cell_w - 1, y + self.cell_h - 1], fill=255)
        self.uv = np.array([self._uv(i) for i in range(count)], dtype=np.float32)

    def _origin(self, i: int) -> tuple[int, int]:
        return (i % COLUMNS) * self.cell_w, (i // COLUMNS) * self.cell_h

    def _uv(self, i: int) -> tuple[float, float, float, float]:
        x, y = self._origin(i)
        w, h = self.image.size
        # Half a texel inwards so linear filtering never bleeds in the neighbouring glyph.
        return ((x + 0.5) / w, (y + 0.5) / h, (x + self.cell_w - 0.5) / w, (y + self.cell_h - 0.5) / h)

    def index(self, ch: str) -> int:
        if ch == PANEL:
            return LAST - FIRST + 1
        c = ord(ch)
        return c - FIRST if FIRST <= c <= LAST else ord("?") - FIRST


class TextOverlay:
    """Lines of text in the bottom-left corner over a translucent panel."""

    def __init__(self, ctx, size: int = 15) -> None:
        self.ctx = ctx
        self.atlas = FontAtlas(size)
        img = self.atlas.image
        self.texture = ctx.texture(img.size, 1, img.tobytes())
        self.texture.filter = (ctx.NEAREST, ctx.NEAREST)  # pixel-aligned cells: keep glyphs crisp
        self.program = ctx.program(vertex_shader=TEXT_VS, fragment_shader=TEXT_FS)
        self.corners = ctx.buffer(quad_strip().tobytes())
        self.instances = ctx.buffer(reserve=64 * 12 * 4, dynamic=True)
        self._uploaded, self._count, self._screen = None, 0, None
        self._vao()

    def _vao(self) -> None:
        self.vao = self.ctx.vertex_array(self.program, [
            (self.corners, "2f", "in_corner"),
            (self.instances, "4f 4f 4f/i", "i_rect", "i_uv", "i_color"),
        ])

    def instances_for(self, lines: list[tuple[str, tuple]], screen_h: int, margin: int = 10,
                      pad: int = 6) -> np.ndarray:
        """(N, 12) instance rows: one panel, then one row per visible glyph. The panel sits
        bottom-left, over the floor: the camera frames the performers in the upper part
        of the picture (it looks down at them), so text there would cover their heads."""
        a = self.atlas
        width = max((len(t) for t, _ in lines), default=0) * a.cell_w
        height = len(lines) * a.cell_h + 2 * pad
        top = max(margin, screen_h - margin - height)
        rows = [(margin, top, width + 2 * pad, height, *a.uv[a.index(PANEL)], 0.0, 0.0, 0.0, 0.55)]
        for n, (text, colour) in enumerate(lines):
            y = top + pad + n * a.cell_h
            for k, ch in enumerate(text):
                if ch != " ":
                    rows.append((margin + pad + k * a.cell_w, y, a.cell_w, a.cell_h,
                                 *a.uv[a.index(ch)], *colour))
        return np.array(rows, dtype=np.float32)

    def draw(self, lines: list[tuple[str, tuple]], screen: tuple[int, int]) -> None:
        if not lines:
            return
        if lines is not self._uploaded or screen != self._screen:  # the viewer hands the same list until it changes
            data = self.instances_for(lines, screen[1])
            if data.nbytes > self.instances.size:
                self.instances.release()
                self.vao.release()
                self.instances = self.ctx.buffer(reserve=data.nbytes * 2, dynamic=True)
                self._vao()
            self.instances.orphan()
            self.instances.write(data.tobytes())
            self._uploaded, self._count, self._screen = lines, len(data), tuple(screen)
        self.program["u_screen"].value = tuple(float(s) for s in screen)
        self.texture.use(0)
        self.program["u_atlas"].value = 0
        self.ctx.disable(self.ctx.DEPTH_TEST)
        self.ctx.enable(self.ctx.BLEND)
        self.ctx.blend_func = self.ctx.SRC_ALPHA, self.ctx.ONE_MINUS_SRC_ALPHA
        self.vao.render(self.ctx.TRIANGLE_STRIP, vertices=4, instances=self._count)
