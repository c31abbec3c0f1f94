// Nishita sky precomputation. See sky_nishita.h; the physics and constants
// are Blender's (intern/sky/source/sky_nishita.cpp, Apache-2.0, Copyright
// 2011-2020 Blender Foundation), kept operation for operation so that the
// image agrees with Cycles' to float rounding.
#include "sky_nishita.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>
#include <vector>

#include "../core/vec.h"

namespace coherent::nishita {

namespace {

constexpr float kRayleighScale = 8e3f;        // Rayleigh scale height (m)
constexpr float kMieScale = 1.2e3f;           // Mie scale height (m)
constexpr float kMieCoeff = 2e-5f;            // Mie scattering coefficient (1/m)
constexpr float kMieG = 0.76f;                // aerosol anisotropy
constexpr float kSqrG = kMieG * kMieG;
constexpr float kEarthRadius = 6360e3f;       // m
constexpr float kAtmosphereRadius = 6420e3f;  // m
constexpr int kSteps = 32;                    // segments of the view ray
constexpr int kWavelengths = 21;              // 380 ... 780 nm
constexpr float kStepLambda = 20.0f;          // nm between wavelengths

// Sun irradiance on top of the atmosphere (W m^-2 nm^-1).
constexpr float kIrradiance[kWavelengths] = {
    1.45756829855592995315f, 1.56596305559738380175f, 1.65148449067670455293f, 1.71496242737209314555f,
    1.75797983805020541226f, 1.78256407885924539336f, 1.79095108475838560302f, 1.78541550133410664714f,
    1.76815554864306845317f, 1.74122069647250410362f, 1.70647127164943679389f, 1.66556087452739887134f,
    1.61993437242451854274f, 1.57083597368892080581f, 1.51932335059305478886f, 1.46628494965214395407f,
    1.41245852740172450623f, 1.35844961970384092709f, 1.30474913844739281998f, 1.25174963272610817455f,
    1.19975998755420620867f};
// Rayleigh scattering coefficient (1/m).
constexpr float kRayleighCoeff[kWavelengths] = {
    0.00005424820087636473f, 0.00004418549866505454f, 0.00003635151910165377f, 0.00003017929012024763f,
    0.00002526320226989157f, 0.00002130859310621843f, 0.00001809838025320633f, 0.00001547057129129042f,
    0.00001330284977336850f, 0.00001150184784075764f, 0.00000999557429990163f, 0.00000872799973630707f,
    0.00000765513700977967f, 0.00000674217203751443f, 0.00000596134125832052f, 0.00000529034598065810f,
    0.00000471115687557433f, 0.00000420910481110487f, 0.00000377218381260133f, 0.00000339051255477280f,
    0.00000305591531679811f};
// Ozone absorption coefficient (1/m).
constexpr float kOzoneCoeff[kWavelengths] = {
    0.00000000325126849861f, 0.00000000585395365047f, 0.00000001977191155085f, 0.00000007309568762914f,
    0.00000020084561514287f, 0.00000040383958096161f, 0.00000063551335912363f, 0.00000096707041180970f,
    0.00000154797400424410f, 0.00000209038647223331f, 0.00000246128056164565f, 0.00000273551299461512f,
    0.00000215125863128643f, 0.00000159051840791988f, 0.00000112356197979857f, 0.00000073527551487574f,
    0.00000046450130357806f, 0.00000033096079921048f, 0.00000022512612292678f, 0.00000014879129266490f,
    0.00000016828623364192f};
// CIE 1931 XYZ colour matching functions at the wavelengths above.
constexpr float kCmfXyz[kWavelengths][3] = {
    {0.00136800000f, 0.00003900000f, 0.00645000100f}, {0.01431000000f, 0.00039600000f, 0.06785001000f},
    {0.13438000000f, 0.00400000000f, 0.64560000000f}, {0.34828000000f, 0.02300000000f, 1.74706000000f},
    {0.29080000000f, 0.06000000000f, 1.66920000000f}, {0.09564000000f, 0.13902000000f, 0.81295010000f},
    {0.00490000000f, 0.32300000000f, 0.27200000000f}, {0.06327000000f, 0.71000000000f, 0.07824999000f},
    {0.29040000000f, 0.95400000000f, 0.02030000000f}, {0.59450000000f, 0.99500000000f, 0.00390000000f},
    {0.91630000000f, 0.87000000000f, 0.00165000100f}, {1.06220000000f, 0.63100000000f, 0.00080000000f},
    {0.85444990000f, 0.38100000000f, 0.00019000000f}, {0.44790000000f, 0.17500000000f, 0.00002000000f},
    {0.16490000000f, 0.06100000000f, 0.00000000000f}, {0.04677000000f, 0.01700000000f, 0.00000000000f},
    {0.01135916000f, 0.00410200000f, 0.00000000000f}, {0.00289932700f, 0.00104700000f, 0.00000000000f},
    {0.00069007860f, 0.00024920000f, 0.00000000000f}, {0.00016615050f, 0.00006000000f, 0.00000000000f},
    {0.00004150994f, 0.00001499000f, 0.00000000000f}};

// Optical depth along a ray to the top of the atmosphere by Gauss-Laguerre
// quadrature (8 nodes, exp(x) folded into the weights, the parameter scaled
// so the last node stays inside the atmosphere): the density falls off
// exponentially along such rays, which this quadrature integrates exactly
// for polynomial remainders.
constexpr int kQuadratureSteps = 8;
constexpr float kQuadratureNodes[kQuadratureSteps] = {0.006811185292f, 0.03614807107f, 0.09004346519f,
                                                      0.1706680068f,   0.2818362161f,  0.4303406404f,
                                                      0.6296271457f,   0.9145252695f};
constexpr float kQuadratureWeights[kQuadratureSteps] = {0.01750893642f, 0.04135477391f, 0.06678839063f,
                                                        0.09507698807f, 0.1283416365f,  0.1707430204f,
                                                        0.2327233347f,  0.3562490486f};

Vec3f geographical_to_direction(float lat, float lon) {
    return {std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
}

Vec3f spectrum_to_xyz(const float* spectrum) {
    Vec3f xyz(0.0f);
    for (int i = 0; i < kWavelengths; i++) {
        xyz.x += kCmfXyz[i][0] * spectrum[i];
        xyz.y += kCmfXyz[i][1] * spectrum[i];
        xyz.z += kCmfXyz[i][2] * spectrum[i];
    }
    return xyz * kStepLambda;
}

float density_rayleigh(float height) { return std::exp(-height / kRayleighScale); }
float density_mie(float height) { return std::exp(-height / kMieScale); }
// Ozone: a tent between 10 and 40 km, peaking at 25 km.
float density_ozone(float height) {
    if (height >= 10000.0f && height < 25000.0f) return 1.0f / 15000.0f * height - 2.0f / 3.0f;
    if (height >= 25000 && height < 40000) return -(1.0f / 15000.0f * height - 8.0f / 3.0f);
    return 0.0f;
}
Vec3f densities(float height) { return {density_rayleigh(height), density_mie(height), density_ozone(height)}; }

float phase_rayleigh(float mu) { return 3.0f / (16.0f * kPi) * (1.0f + mu * mu); }
float phase_mie(float mu) {
    return (3.0f * (1.0f - kSqrG) * (1.0f + mu * mu)) /
           (8.0f * kPi * (2.0f + kSqrG) * std::pow((1.0f + kSqrG - 2.0f * kMieG * mu), 1.5f));
}

// Does the ray from pos along dir hit the ground?
bool hits_earth(const Vec3f& pos, const Vec3f& dir) {
    if (dir.z >= 0) return false;
    const float b = -2.0f * dot(dir, -pos);
    const float c = length_squared(pos) - kEarthRadius * kEarthRadius;
    return b * b - 4.0f * c >= 0.0f;
}

Vec3f atmosphere_exit(const Vec3f& pos, const Vec3f& dir) {
    const float b = -2.0f * dot(dir, -pos);
    const float c = length_squared(pos) - kAtmosphereRadius * kAtmosphereRadius;
    const float t = (-b + std::sqrt(b * b - 4.0f * c)) / 2.0f;
    return {pos.x + dir.x * t, pos.y + dir.y * t, pos.z + dir.z * t};
}

// Rayleigh, Mie and ozone optical depths (per unit coefficient) to the top of the atmosphere.
Vec3f optical_depth_to_space(const Vec3f& origin, const Vec3f& dir) {
    const float ray_length = length(atmosphere_exit(origin, dir) - origin);
    const Vec3f segment = ray_length * dir;
    Vec3f depth(0.0f);
    for (int i = 0; i < kQuadratureSteps; i++) {
        const Vec3f p = origin + kQuadratureNodes[i] * segment;
        depth += densities(length(p) - kEarthRadius) * kQuadratureWeights[i];
    }
    return depth * ray_length;
}

float sum(const Vec3f& v) { return v.x + v.y + v.z; }

// In-scattered spectral radiance along a view ray: midpoint rule over kSteps
// segments, each lit by the sun through the atmosphere unless the Earth is in the way.
void single_scattering(const Vec3f& dir, const Vec3f& sun_dir, const Vec3f& origin, const Vec3f& density_scale,
                       float* spectrum) {
    const float ray_length = length(atmosphere_exit(origin, dir) - origin);
    const float segment_length = ray_length / kSteps;
    const Vec3f segment = segment_length * dir;
    Vec3f optical_depth(0.0f);
    std::fill(spectrum, spectrum + kWavelengths, 0.0f);
    const float mu = dot(dir, sun_dir);
    const Vec3f phase{phase_rayleigh(mu), phase_mie(mu), 0.0f};
    Vec3f p = origin + 0.5f * segment;
    for (int i = 0; i < kSteps; i++) {
        const Vec3f density = density_scale * densities(length(p) - kEarthRadius);
        optical_depth += segment_length * density;
        if (!hits_earth(p, sun_dir)) {
            const Vec3f total_depth = optical_depth + density_scale * optical_depth_to_space(p, sun_dir);
            for (int wl = 0; wl < kWavelengths; wl++) {
                const Vec3f extinction = total_depth * Vec3f(kRayleighCoeff[wl], 1.11f * kMieCoeff, kOzoneCoeff[wl]);
                const float attenuation = std::exp(-sum(extinction));
                const Vec3f scattering = density * Vec3f(kRayleighCoeff[wl], kMieCoeff, 0.0f);
                spectrum[wl] += attenuation * sum(phase * scattering) * kIrradiance[wl] * segment_length;
            }
        }
        p += segment;
    }
}

void precompute_rows(float* xyz, int y_begin, int y_end, int width, int height, const Vec3f& sun_dir,
                     const Vec3f& origin, const Vec3f& density_scale) {
    const float half_pi = 0.5f * kPi;
    const float latitude_step = half_pi / float(height);
    const float longitude_step = 2.0f * kPi / float(width);
    const float half_lat_step = latitude_step / 2.0f;
    float spectrum[kWavelengths];
    for (int y = y_begin; y < y_end; y++) {
        // More rows towards the horizon, where the sky changes fastest.
        const float t = float(y) / float(height);
        const float latitude = (half_pi + half_lat_step) * (t * t);
        float* row = xyz + size_t(y) * size_t(width) * 3;
        for (int x = 0; x < width / 2; x++) {
            const float longitude = longitude_step * float(x) - kPi;
            single_scattering(geographical_to_direction(latitude, longitude), sun_dir, origin, density_scale,
                              spectrum);
            const Vec3f c = spectrum_to_xyz(spectrum);
            // The sky is symmetric about the sun's azimuth.
            for (const int column : {x, width - x - 1})
                for (int k = 0; k < 3; ++k) row[size_t(column) * 3 + size_t(k)] = c[k];
        }
    }
}

}  // namespace

void precompute_texture(float* xyz, int width, int height, float sun_elevation, float altitude, float air_density,
                        float dust_density, float ozone_density) {
    const Vec3f origin{0.0f, 0.0f, kEarthRadius + altitude};
    const Vec3f sun_dir = geographical_to_direction(sun_elevation, 0.0f);
    const Vec3f density_scale{air_density, dust_density, ozone_density};
    std::atomic<int> next_row{0};
    auto work = [&] {
        for (int y; (y = next_row.fetch_add(1)) < height;)
            precompute_rows(xyz, y, y + 1, width, height, sun_dir, origin, density_scale);
    };
    const int threads = int(std::clamp(std::thread::hardware_concurrency(), 1u, 16u));
    std::vector<std::thread> pool;
    for (int i = 1; i < threads; ++i) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
}

void precompute_sun(float sun_elevation, float angular_diameter, float altitude, float air_density,
                    float dust_density, float bottom[3], float top[3]) {
    const float half_angular = angular_diameter / 2.0f;
    const float solid_angle = 2.0f * kPi * (1.0f - std::cos(half_angular));
    const Vec3f origin{0.0f, 0.0f, kEarthRadius + altitude};
    // The sun's radiance through the atmosphere towards elevation e (XYZ).
    auto sun_at = [&](float elevation) {
        const Vec3f depth = optical_depth_to_space(origin, geographical_to_direction(std::max(elevation, 0.0f), 0.0f));
        float spectrum[kWavelengths];
        for (int i = 0; i < kWavelengths; i++) {
            const float tau = kRayleighCoeff[i] * depth.x * air_density + 1.11f * kMieCoeff * depth.y * dust_density;
            spectrum[i] = kIrradiance[i] * std::exp(-tau) / solid_angle;
        }
        return spectrum_to_xyz(spectrum);
    };
    const Vec3f b = sun_at(sun_elevation - half_angular), t = sun_at(sun_elevation + half_angular);
    for (int k = 0; k < 3; ++k) {
        bottom[k] = b[k];
        top[k] = t[k];
    }
}

}  // namespace coherent::nishita
