"""Drawing the arena with pygame: a leaf module, imported only when rendering is asked for.

Robots are coloured by speed class (fast red, medium green, slow blue, others grey) with a ring in
the colour of the circuit they serve; broken robots are hollow circles with a cross; each moving
robot has a line to its current target; stations are squares (sources) and diamonds (sinks) in
their circuit's colour. A readout shows the simulated time, the `f:s` state (robots of each class on
the high-value circuit), the robots per circuit and the delivered value; a legend names the
colours: each speed class with its speed, each circuit with its value.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from tavc_env.config import ArenaConfig
from tavc_env.engine.simulation import ArenaSnapshot

try:
    import pygame
except ImportError as error:  # pragma: no cover - depends on the installation
    raise ImportError(
        "rendering needs pygame, an optional extra: pip install 'tavc-env[render]'"
    ) from error

PIXELS_PER_M = 60
MARGIN_PX = 10
PANEL_PX = 106
CLASS_COLOURS = {"fast": (220, 60, 50), "medium": (40, 160, 70), "slow": (50, 90, 220)}
OTHER_COLOUR = (120, 120, 120)
CIRCUIT_COLOURS = [(230, 160, 20), (150, 70, 190), (20, 160, 200), (140, 90, 40), (200, 80, 140)]


class Renderer:
    """Draws one env's arena to a surface; shows it in a window in "human" mode."""

    def __init__(self, config: ArenaConfig, mode: str) -> None:
        self.config = config
        self.mode = mode
        if mode != "human":
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        pygame.init()
        self.size = (
            int(config.width * PIXELS_PER_M) + 2 * MARGIN_PX,
            int(config.height * PIXELS_PER_M) + 2 * MARGIN_PX + PANEL_PX,
        )
        self.surface = pygame.Surface(self.size)
        self.window: Any = None
        self.font = pygame.font.Font(None, 22)
        # speed classes, fastest first, with their (top) speeds: the readout and the legend
        speeds: dict[str, float] = {}
        for r in config.robots:
            speeds[r.speed_class] = max(speeds.get(r.speed_class, 0.0), r.speed)
        self.class_speeds = dict(sorted(speeds.items(), key=lambda item: -item[1]))

    def _px(self, p: np.ndarray | tuple[float, float]) -> tuple[int, int]:
        x = MARGIN_PX + p[0] * PIXELS_PER_M
        y = MARGIN_PX + (self.config.height - p[1]) * PIXELS_PER_M
        return round(x), round(y)

    def draw(self, sim: ArenaSnapshot, delivered_value: float) -> np.ndarray | None:
        """Draw the arena as `sim` shows it, with `delivered_value` (w / max w per delivery since
        reset) in the readout; the frame in "rgb_array" mode, None in "human" mode."""
        cfg = self.config
        surf = self.surface
        surf.fill((250, 250, 245))
        top_left = self._px((0.0, cfg.height))
        pygame.draw.rect(
            surf,
            (40, 40, 40),
            (*top_left, int(cfg.width * PIXELS_PER_M), int(cfg.height * PIXELS_PER_M)),
            3,
        )
        half = int(0.18 * PIXELS_PER_M)
        for c, circuit in enumerate(cfg.circuits):
            colour = CIRCUIT_COLOURS[c % len(CIRCUIT_COLOURS)]
            sx, sy = self._px(circuit.source)
            pygame.draw.rect(surf, colour, (sx - half, sy - half, 2 * half, 2 * half))
            kx, ky = self._px(circuit.sink)
            pygame.draw.polygon(
                surf, colour, [(kx, ky - half), (kx + half, ky), (kx, ky + half), (kx - half, ky)]
            )
        pos = sim.positions
        radius = int(cfg.robot_radius * PIXELS_PER_M)
        moving = sim.moving
        broken = sim.broken
        for i, robot in enumerate(cfg.robots):
            centre = self._px(pos[i])
            colour = CLASS_COLOURS.get(robot.speed_class, OTHER_COLOUR)
            if moving[i]:
                pygame.draw.line(surf, (180, 180, 180), centre, self._px(sim.targets[i]), 1)
            if broken[i]:
                pygame.draw.circle(surf, colour, centre, radius, 2)
                d = int(radius * 0.7)
                x, y = centre
                pygame.draw.line(surf, colour, (x - d, y - d), (x + d, y + d), 2)
                pygame.draw.line(surf, colour, (x - d, y + d), (x + d, y - d), 2)
                continue
            pygame.draw.circle(surf, colour, centre, radius)
            tip = pos[i] + cfg.robot_radius * np.array(
                [np.cos(sim.headings[i]), np.sin(sim.headings[i])]
            )
            pygame.draw.line(surf, (255, 255, 255), centre, self._px(tip), 2)
            ring = CIRCUIT_COLOURS[int(sim.circuits[i]) % len(CIRCUIT_COLOURS)]
            pygame.draw.circle(surf, ring, centre, radius, 3)
        counts = np.bincount(sim.circuits[~broken], minlength=cfg.n_circuits)
        high = int(np.argmax(sim.values))
        labels = list(self.class_speeds)
        on_high = [
            sum(
                1
                for i, r in enumerate(cfg.robots)
                if r.speed_class == label and not broken[i] and sim.circuits[i] == high
            )
            for label in labels
        ]
        state = ":".join(str(k) for k in on_high)
        lines = [
            f"t = {sim.time_s / 3600.0:6.2f} h   {'/'.join(labels)} on circuit {high}: {state}   "
            f"robots per circuit: {counts.tolist()}",
            f"delivered value: {delivered_value:.1f} (w / max w per delivery)   "
            f"broken: {int(broken.sum())}",
        ]
        for k, text in enumerate(lines):
            label = self.font.render(text, True, (20, 20, 20))
            surf.blit(label, (MARGIN_PX, self.size[1] - PANEL_PX + 8 + 22 * k))
        self._legend(sim.values, self.size[1] - PANEL_PX + 8 + 44)
        if self.mode == "human":
            if self.window is None:
                pygame.display.init()
                self.window = pygame.display.set_mode(self.size)
            self.window.blit(surf, (0, 0))
            pygame.event.pump()
            pygame.display.flip()
            return None
        return np.transpose(pygame.surfarray.array3d(surf), (1, 0, 2)).copy()

    def _legend(self, values: np.ndarray, y: int) -> None:
        """Two lines: a disc per speed class (with its speed) and a square per circuit (with its
        value), then what rings, shapes and lines mean."""
        cfg = self.config
        x = MARGIN_PX
        items: list[tuple[str, tuple[int, int, int], str]] = []
        for label, speed in self.class_speeds.items():
            items.append(
                ("disc", CLASS_COLOURS.get(label, OTHER_COLOUR), f"{label} {speed:.2f} m/s")
            )
        high = int(np.argmax(values))
        for c in range(cfg.n_circuits):
            mark = " (high)" if c == high else ""
            colour = CIRCUIT_COLOURS[c % len(CIRCUIT_COLOURS)]
            items.append(("square", colour, f"circuit {c}: w {values[c]:g}{mark}"))
        for shape, colour, text in items:
            if shape == "disc":
                pygame.draw.circle(self.surface, colour, (x + 6, y + 7), 6)
            elif shape == "square":
                pygame.draw.rect(self.surface, colour, (x, y + 1, 12, 12))
            x += 16
            written = self.font.render(text, True, (20, 20, 20))
            self.surface.blit(written, (x, y))
            x += written.get_width() + 14
        key = "ring: the circuit a robot serves; square: source, diamond: sink; line: to its target"
        self.surface.blit(self.font.render(key, True, (20, 20, 20)), (MARGIN_PX, y + 22))

    def close(self) -> None:
        if self.window is not None:
            pygame.display.quit()
            self.window = None
