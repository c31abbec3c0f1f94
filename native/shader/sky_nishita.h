// The Nishita sky's precomputation (used by sky_model.cpp): single
// scattering of sunlight by air (Rayleigh), dust (Mie) and ozone
// (absorption) in a spherical atmosphere, integrated over 21 wavelengths and
// converted to CIE XYZ. A port of Blender 3.4's intern/sky/source/
// sky_nishita.cpp (Apache-2.0, Copyright 2011-2020 Blender Foundation), with
// the same constants, quadrature and float arithmetic so that the image
// matches Cycles' to float rounding.
#pragma once

namespace coherent::nishita {

// Cycles' SkyLoader image size.
constexpr int kImageWidth = 512;
constexpr int kImageHeight = 128;

// XYZ of the sky over width x height texels (3 floats each, row-major): row
// y looks at elevation (pi/2 + half a row) (y / height)^2 above the horizon,
// column x at azimuth 2 pi x / width - pi from the sun (mirrored about it).
// Rows are computed in parallel.
void precompute_texture(float* xyz, int width, int height, float sun_elevation, float altitude, float air_density,
                        float dust_density, float ozone_density);

// XYZ radiance of the sun disc (of angular diameter `angular_diameter`) seen
// through the atmosphere at its lower and upper edge (clamped to the horizon).
void precompute_sun(float sun_elevation, float angular_diameter, float altitude, float air_density,
                    float dust_density, float bottom[3], float top[3]);

}  // namespace coherent::nishita
