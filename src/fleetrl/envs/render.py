"""Small ``rgb_array`` frames of a unit's state, drawn with numpy alone (no display, no extra package)."""

import math

import numpy as np

FRAME = 200  # frame height and width in pixels
ARM, PENDULUM, CART, TRACK = (40, 90, 160), (200, 60, 40), (60, 60, 60), (170, 170, 170)


def blank() -> np.ndarray:
    """A white frame."""
    return np.full((FRAME, FRAME, 3), 255, dtype=np.uint8)


def line(
    img: np.ndarray,
    start: tuple[float, float],
    end: tuple[float, float],
    color: tuple[int, ...],
    width: int = 3,
) -> None:
    """Draw a thick segment between two (x, y) pixel points (y down), clipped to the frame."""
    n = int(max(abs(end[0] - start[0]), abs(end[1] - start[1]))) + 1
    xs = np.rint(np.linspace(start[0], end[0], n)).astype(int)
    ys = np.rint(np.linspace(start[1], end[1], n)).astype(int)
    half = width // 2
    for dx in range(-half, half + 1):
        for dy in range(-half, half + 1):
            x, y = xs + dx, ys + dy
            keep = (x >= 0) & (x < img.shape[1]) & (y >= 0) & (y < img.shape[0])
            img[y[keep], x[keep]] = color


def qube_frame(obs: np.ndarray) -> np.ndarray:
    """Left: the arm seen from above (angle θ); right: the pendulum seen from the front (α, 0 = upright)."""
    alpha, theta = float(obs[0]), float(obs[2])
    img = blank()
    cx, cy, r = FRAME * 0.25, FRAME * 0.5, FRAME * 0.2
    line(img, (cx, cy), (cx + r * math.sin(theta), cy - r * math.cos(theta)), ARM, 5)
    px, py, length = FRAME * 0.75, FRAME * 0.75, FRAME * 0.5
    line(img, (px - 25, py), (px + 25, py), TRACK, 3)
    line(img, (px, py), (px + length * math.sin(alpha), py - length * math.cos(alpha)), PENDULUM, 5)
    return img


def cartpole_frame(obs: np.ndarray) -> np.ndarray:
    """The cart on its track (±2.4 m across the frame) and the pole (θ, 0 = upright)."""
    x, theta = float(obs[0]), float(obs[2])
    img = blank()
    track_y, scale = FRAME * 0.75, FRAME / 5.6
    line(img, (0, track_y), (FRAME - 1, track_y), TRACK, 1)
    cart_x = FRAME / 2 + x * scale
    line(img, (cart_x - 12, track_y - 5), (cart_x + 12, track_y - 5), CART, 9)
    length = FRAME * 0.4
    line(
        img,
        (cart_x, track_y - 10),
        (cart_x + length * math.sin(theta), track_y - 10 - length * math.cos(theta)),
        PENDULUM,
        5,
    )
    return img
