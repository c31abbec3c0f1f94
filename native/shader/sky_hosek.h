// Hosek / Wilkie sky model: cooking the per-channel configuration of the XYZ
// model for one turbidity, ground albedo and solar elevation (used by
// sky_model.cpp). A port of ArHosekSkyModel_CookConfiguration and
// ArHosekSkyModel_CookRadianceConfiguration from Blender 3.4's
// intern/sky/source/sky_model.cpp (BSD-3-Clause, Copyright 2012-2013 Lukas
// Hosek and Alexander Wilkie), in double precision as there.
#pragma once

namespace coherent::hosek {

// turbidity in [1, 10], albedo in [0, 1], solar elevation in radians
// [0, pi/2]. Fills the 9 parameters of each XYZ channel and its radiance scale.
void xyz_configuration(double turbidity, double albedo, double solar_elevation, double config[3][9],
                       double radiance[3]);

}  // namespace coherent::hosek
