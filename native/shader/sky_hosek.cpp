// Hosek / Wilkie configuration cooking. See sky_hosek.h. The coefficient
// tables (sky_hosek_data.h) hold, per albedo (0 and 1) and integer turbidity
// (1 ... 10), six control points of a quintic Bezier curve over
// (elevation / (pi/2))^(1/3); a configuration is that curve, blended linearly
// between the two albedos and the two neighbouring turbidities.
#include "sky_hosek.h"

#include <cmath>

#include "sky_hosek_data.h"

namespace coherent::hosek {

namespace {

constexpr double kHalfPi = 3.141592653589793 / 2.0;

// The Bezier curve through control points c[0], c[stride], ... c[5 stride] at t.
double quintic(const double* c, int stride, double t) {
    return std::pow(1.0 - t, 5.0) * c[0] + 5.0 * std::pow(1.0 - t, 4.0) * t * c[stride] +
           10.0 * std::pow(1.0 - t, 3.0) * std::pow(t, 2.0) * c[2 * stride] +
           10.0 * std::pow(1.0 - t, 2.0) * std::pow(t, 3.0) * c[3 * stride] +
           5.0 * (1.0 - t) * std::pow(t, 4.0) * c[4 * stride] + std::pow(t, 5.0) * c[5 * stride];
}

// Blends `value(offset of the (albedo, turbidity) block)` over the four
// corners, in the order the reference sums them (so rounding agrees).
template <class Value>
double blend(double turbidity, double albedo, int block, const Value& value) {
    const int t = int(turbidity);
    const double rem = turbidity - double(t);
    double res = (1.0 - albedo) * (1.0 - rem) * value(block * (t - 1));
    res += albedo * (1.0 - rem) * value(block * 10 + block * (t - 1));
    if (t == 10) return res;
    res += (1.0 - albedo) * rem * value(block * t);
    res += albedo * rem * value(block * 10 + block * t);
    return res;
}

}  // namespace

void xyz_configuration(double turbidity, double albedo, double solar_elevation, double config[3][9],
                       double radiance[3]) {
    const double e = std::pow(solar_elevation / kHalfPi, 1.0 / 3.0);
    for (int channel = 0; channel < 3; ++channel) {
        const double* data = sky_data::kHosekXYZ[channel];
        for (int i = 0; i < 9; ++i)
            config[channel][i] = blend(turbidity, albedo, 9 * 6, [&](int offset) { return quintic(data + offset + i, 9, e); });
        const double* rad = sky_data::kHosekXYZRadiance[channel];
        radiance[channel] = blend(turbidity, albedo, 6, [&](int offset) { return quintic(rad + offset, 1, e); });
    }
}

}  // namespace coherent::hosek
