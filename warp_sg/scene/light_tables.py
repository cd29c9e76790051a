r"""The ``[[lights]]`` tables, once: the pydantic models of point, directional and environment
lights (:data:`LIGHT_MODELS`, the union :data:`LightTable` on ``type``), each key's rule, default
and meaning. They are the one check of a light: the TOML loader validates ``[[lights]]`` with them
(as part of :class:`warp_sg.scene.schema.SceneFile`), the light records of
:mod:`warp_sg.scene.lights` built in Python check their fields with the same models (and take
their defaults from them, :func:`default_of`), and ``warp-sg schema`` shows their rules and meanings.
"""
from __future__ import annotations

import inspect
import math
from typing import Annotated, Literal

from pydantic import Field, create_model

from warp_sg.scene.envmap import MAX_RADIANCE
from warp_sg.scene.sky import procedural_sky
from warp_sg.scene.values import Table, anything, fail, integer, number, path, plain, require_tag, rgb, tagged, vector

#: the built-in maps of an environment light (``procedural = ...``)
ENV_PROCEDURAL = ("sky", "constant")


def default_of(model, key):
    """The default of ``key`` in the table ``model`` (what a record built in Python takes too)."""
    return model.model_fields[key].default


class PointLightTable(Table):
    """A spherical light: radiance s/(π r²), irradiance s/d² at distance d."""

    type: Annotated[Literal["point"], Field(description="light type")]
    position: vector(description="centre")
    radius: number(lo=0, description="radius (0: a delta light)") = 0.1
    intensity: rgb(hi=MAX_RADIANCE, description="intensity s (W/sr): number or RGB") = [1.0, 1.0, 1.0]


class DirectionalLightTable(Table):
    """A distant light (a sun)."""

    type: Annotated[Literal["directional"], Field(description="light type")]
    direction: vector(nonzero=True, description="direction towards the light")
    radius: number(lo=0, hi=math.pi / 2, description="angular radius (radians)") = 0.02
    intensity: rgb(hi=MAX_RADIANCE, description="irradiance E on a surface facing the light: number or RGB") = [1.0, 1.0, 1.0]


_SKY_TYPES = {  # procedural_sky's keywords (envmap.procedural_sky needs width, height >= 2)
    "width": integer(lo=2, description="map width (texels)"),
    "height": integer(lo=2, description="map height (texels)"),
    "sun_direction": vector(nonzero=True, description="direction towards the sun"),
    "sun_angular_radius": number(lo=0, description="sun disk radius (radians)"),
    "sun_intensity": number(lo=0, description="sun radiance"),
    "sun_color": rgb(raw=True, description="sun colour (number or RGB)"),
    "zenith_color": rgb(raw=True, description="sky colour at the zenith"),
    "horizon_color": rgb(raw=True, description="sky colour at the horizon"),
    "ground_color": rgb(raw=True, description="colour below the horizon"),
    "sky_intensity": number(lo=0, description="sky radiance scale"),
    "halo": number(lo=0, description="strength of the glow around the sun"),
    "horizon_blur": number(lo=0, description="width of the horizon transition"),
    "supersample": integer(lo=1, description="sub-cells per texel side (box filter)"),
}
SkyOptions = create_model(
    "SkyOptions", __base__=Table, __doc__="Keywords of warp_sg.scene.sky.procedural_sky.",
    **{k: (_SKY_TYPES.get(k) or anything({}, f"procedural_sky keyword {k}"),
           Field(None, json_schema_extra={"default": plain(p.default)}))
       for k, p in inspect.signature(procedural_sky).parameters.items()})


class ConstantOptions(Table):
    """A uniform environment."""

    radiance: rgb(raw=True, hi=MAX_RADIANCE, description="radiance (number or RGB)") = None
    width: integer(lo=1, description="map width (texels)") = None
    height: integer(lo=1, description="map height (texels)") = None


class _Environment(Table):
    type: Annotated[Literal["environment"], Field(description="light type")]
    scale: number(lo=0, hi=MAX_RADIANCE, description="radiance scale") = 1.0
    rotation: number(description="rotation about +Y (degrees)") = 0.0


class EnvironmentData(_Environment):
    """An environment whose radiance is given as an array (``EnvironmentLight(data=...)``, Python only)."""


class EnvironmentFile(_Environment):
    """An equirectangular environment map (Mitsuba convention) from a file."""

    file: path("equirectangular map (EXR or Radiance .hdr), relative to the scene file")


class EnvironmentSky(_Environment):
    """The procedural all-frequency sky: gradient, ground, halo and a small bright sun."""

    procedural: Annotated[Literal["sky"], Field(description="built-in map")]
    options: Annotated[SkyOptions, Field(description="warp_sg.scene.sky.procedural_sky keywords")] = None


class EnvironmentConstant(_Environment):
    """A uniform environment."""

    procedural: Annotated[Literal["constant"], Field(description="built-in map")]
    options: Annotated[ConstantOptions, Field(description="radiance, width, height")] = None


LIGHT_MODELS = {"<point>": PointLightTable, "<directional>": DirectionalLightTable,
                "<environment file>": EnvironmentFile, "<environment sky>": EnvironmentSky,
                "<environment constant>": EnvironmentConstant}
LIGHT_TYPES = ("point", "directional", "environment")


def _light_tag(v):
    require_tag(v, "type", LIGHT_TYPES, "light type")
    if v["type"] == "environment":
        if ("file" in v) == ("procedural" in v):
            fail("give exactly one of 'file' or 'procedural'")
        if "procedural" in v and v["procedural"] not in ENV_PROCEDURAL:
            fail(f"must be {' or '.join(repr(p) for p in ENV_PROCEDURAL)}, got {v['procedural']!r}",
                 key="procedural")
    return v


def _light_branch(v) -> str:
    if v["type"] != "environment":
        return f"<{v['type']}>"
    return "<environment file>" if "file" in v else f"<environment {v['procedural']}>"


LightTable = tagged(LIGHT_MODELS, _light_branch, _light_tag)


__all__ = ["LIGHT_MODELS", "LIGHT_TYPES", "LightTable", "PointLightTable", "DirectionalLightTable", "EnvironmentFile",
           "EnvironmentSky", "EnvironmentConstant", "EnvironmentData", "SkyOptions", "ConstantOptions", "ENV_PROCEDURAL",
           "default_of"]
