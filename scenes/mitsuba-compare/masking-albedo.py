#!/usr/bin/env python3
"""The directional albedo of a white (F = 1) Trowbridge-Reitz reflector and of a rough
dielectric (reflected plus transmitted energy) with the height-correlated Smith G (pbrt-v4,
vmerge) and the separable one (Mitsuba 3), by quadrature over the sphere of directions in f64;
then the image means both predict for furnace-conductor-rough.pbrt. Needs numpy (the Mitsuba
venv has it). Usage: python3 masking-albedo.py
"""
import numpy as np


def lam(alpha, cos):
    cos = np.clip(cos, 1e-12, 1.0)
    tan2 = (1.0 - cos * cos) / (cos * cos)
    return (-1.0 + np.sqrt(1.0 + alpha * alpha * tan2)) / 2.0


def ggx(alpha, cos_h):
    c2 = cos_h * cos_h
    tan2 = (1.0 - c2) / c2
    return 1.0 / (np.pi * alpha * alpha * c2 * c2 * (1.0 + tan2 / (alpha * alpha)) ** 2)


def fresnel(cos_i, eta):
    """Unpolarised dielectric Fresnel reflectance from outside (eta = inside / outside)."""
    sin2_t = (1.0 - cos_i * cos_i) / eta ** 2
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, 1.0))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return np.where(sin2_t >= 1.0, 1.0, (rs * rs + rp * rp) / 2.0)


class Sphere:
    """Midpoint quadrature over all directions: n polar x 2n azimuthal cells."""

    def __init__(self, n):
        theta = (np.arange(n) + 0.5) / n * np.pi
        phi = (np.arange(2 * n) + 0.5) / (2 * n) * 2.0 * np.pi
        t, p = np.meshgrid(theta, phi, indexing="ij")
        self.dw = np.sin(t) * (np.pi / n) * (np.pi / n)
        self.wi = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)

    def albedo(self, alpha, theta_o, eta=None):
        """{form: albedo} for both forms of G from wo at theta_o."""
        wo = np.array([np.sin(theta_o), 0.0, np.cos(theta_o)])
        wi, cos_o, cos_i = self.wi, wo[2], self.wi[..., 2]
        up = cos_i > 0
        out = {}
        for form in ("correlated", "separable"):
            lo, li = lam(alpha, cos_o), lam(alpha, np.abs(cos_i))
            g = 1 / (1 + lo + li) if form == "correlated" else 1 / ((1 + lo) * (1 + li))
            h = wo + wi
            h /= np.linalg.norm(h, axis=-1, keepdims=True)
            f_r = np.where(up & (h[..., 2] > 0),
                           ggx(alpha, np.abs(h[..., 2])) * g / (4 * cos_o * np.maximum(cos_i, 1e-12)),
                           0.0)
            if eta is None:
                out[form] = np.sum(f_r * np.abs(cos_i) * self.dw)
                continue
            f_r = f_r * fresnel(np.clip(np.sum(wo * h, -1), 0, 1), eta)
            # Walter et al. 2007 transmission with the generalised half vector, as energy (the
            # radiance scale eta^2 left out).
            ht = -(wo + eta * wi)
            ht /= np.linalg.norm(ht, axis=-1, keepdims=True)
            ht *= np.sign(ht[..., 2:3])
            oh, ih = np.sum(wo * ht, -1), np.sum(wi * ht, -1)
            f_t = np.where((~up) & (oh > 0) & (ih < 0),
                           ggx(alpha, ht[..., 2]) * g * (1 - fresnel(np.clip(oh, 0, 1), eta))
                           * eta * eta * np.abs(ih) * oh
                           / (cos_o * np.abs(cos_i) * (oh + eta * ih) ** 2),
                           0.0)
            out[form] = np.sum((f_r + f_t) * np.abs(cos_i) * self.dw)
        return out


def main():
    fine = Sphere(1600)
    angles = (0, 45, 70, 85)
    print("white conductor: albedo at 0 deg (both forms), then separable / correlated - 1")
    for alpha in (0.1, 0.316228, 0.5, 1.0):
        cells = [fine.albedo(alpha, np.radians(a)) for a in angles]
        print(f"  alpha {alpha}: {cells[0]['correlated']:.4f}; " + ", ".join(
            f"{a} deg {c['separable'] / c['correlated'] - 1:+.2%}" for a, c in zip(angles, cells)))
    cells = [fine.albedo(0.316228, np.radians(a), eta=1.5) for a in angles]
    print("rough dielectric eta 1.5, alpha 0.316228: " + ", ".join(
        f"{a} deg {c['correlated']:.4f} / {c['separable']:.4f} ({c['separable'] / c['correlated'] - 1:+.2%})"
        for a, c in zip(angles, cells)))
    coarse = Sphere(800)
    # A sphere seen from afar: cos theta_o distributed as 2 mu dmu over its disk.
    mus = (np.arange(24) + 0.5) / 24
    for label, eta in (("conductor", None), ("dielectric", 1.5)):
        cells = [coarse.albedo(0.316228, np.arccos(m), eta) for m in mus]
        means = {form: sum(2 * m * c[form] for m, c in zip(mus, cells)) / len(mus)
                 for form in ("correlated", "separable")}
        print(f"disk mean, {label} alpha 0.316228: {means['correlated']:.4f} / "
              f"{means['separable']:.4f} ({means['separable'] / means['correlated'] - 1:+.2%})")
    # furnace-conductor-rough: 64x64 pixels of 4x4 points each, fov 40 degrees, the camera at
    # distance 3 from a unit sphere under a sky of radiance 1.
    alpha = 0.5
    table_mu = np.linspace(0.02, 1.0, 50)
    table = [coarse.albedo(alpha, np.arccos(m)) for m in table_mu]
    side = 64 * 4
    x = ((np.arange(side) + 0.5) / side * 2 - 1) * np.tan(np.radians(20))
    px, py = np.meshgrid(x, x)
    d = np.stack([px, py, -np.ones_like(px)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    origin = np.array([0.0, 0.0, 3.0])
    b = d @ origin
    disc = b * b - (origin @ origin - 1)
    hit = disc > 0
    t = -b - np.sqrt(np.where(hit, disc, 0))
    mu = np.where(hit, -np.sum((origin + t[..., None] * d) * d, -1), 0)
    means = {}
    for form in ("correlated", "separable"):
        a = np.interp(mu, table_mu, [c[form] for c in table])
        means[form] = np.where(hit, a, 1.0).mean()
    print(f"furnace-conductor-rough image mean: correlated {means['correlated']:.5f}, separable "
          f"{means['separable']:.5f}, ratio {means['correlated'] / means['separable']:.4f}")


if __name__ == "__main__":
    main()
