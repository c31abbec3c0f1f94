// Python bindings of the Sky Texture (shader/sky_model.h): the module function
// sky_texture() precomputes a sky into its packed float form (what a shader
// program's data and Scene.set_world_sky take), Scene.set_world_sky makes it
// the world, and Scene.world_radiance evaluates the world as camera rays that
// miss everything see it (tests compare that with Cycles).
#include <cmath>
#include <cstring>
#include <memory>
#include <string>

#include "bindings.h"
#include "render/world_sampling.h"
#include "shader/sky_model.h"
#include "shader/sky_world.h"

namespace coherent::python {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

SkyType sky_type_from(const std::string& name) {
    if (name == "PREETHAM") return SkyType::Preetham;
    if (name == "HOSEK_WILKIE") return SkyType::HosekWilkie;
    if (name == "NISHITA") return SkyType::Nishita;
    throw py::value_error("sky_type: expected 'PREETHAM', 'HOSEK_WILKIE' or 'NISHITA', got '" + name + "'");
}

float non_negative(double v, const char* arg) {
    const float f = finite_float(v, arg);
    if (f < 0.0f) throw py::value_error(std::string(arg) + ": must be >= 0, got " + std::to_string(v));
    return f;
}

py::array_t<float> sky_texture(const std::string& type, const py::handle& sun_direction, double turbidity,
                               double ground_albedo, bool sun_disc, double sun_size, double sun_intensity,
                               double sun_elevation, double sun_rotation, double altitude, double air_density,
                               double dust_density, double ozone_density) {
    SkyInputs in;
    in.type = sky_type_from(type);
    in.sun_direction = to_vec3(sun_direction, "sun_direction");
    if (!(length(in.sun_direction) > 0.0f)) throw py::value_error("sun_direction: must not be zero");
    in.turbidity = finite_float(turbidity, "turbidity");
    if (in.turbidity < 1.0f || in.turbidity > 10.0f)
        throw py::value_error("turbidity: must be in [1, 10], got " + std::to_string(turbidity));
    in.ground_albedo = finite_float(ground_albedo, "ground_albedo");
    in.sun_disc = sun_disc;
    in.sun_size = non_negative(sun_size, "sun_size");
    in.sun_intensity = non_negative(sun_intensity, "sun_intensity");
    in.sun_elevation = finite_float(sun_elevation, "sun_elevation");
    in.sun_rotation = finite_float(sun_rotation, "sun_rotation");
    in.altitude = finite_float(altitude, "altitude");
    in.air_density = non_negative(air_density, "air_density");
    in.dust_density = non_negative(dust_density, "dust_density");
    in.ozone_density = non_negative(ozone_density, "ozone_density");
    std::vector<float> packed;
    {
        py::gil_scoped_release unlocked;
        packed = pack(precompute_sky(in));
    }
    py::array_t<float> out(py::ssize_t(packed.size()));
    std::memcpy(out.mutable_data(), packed.data(), packed.size() * sizeof(float));
    return out;
}

// A SkyTexture from its packed form, checked (a wrong array is a ValueError, not a crash).
std::shared_ptr<SkyTexture> unpack(const py::handle& obj) {
    FloatArray a = FloatArray::ensure(obj);
    if (!a || a.ndim() != 1 || size_t(a.shape(0)) < kSkyParamFloats)
        throw py::value_error("sky: expected the 1-D float array sky_texture() returns");
    if (!packed_sky_valid(a.data(), size_t(a.shape(0))) || packed_sky_floats(a.data()) != size_t(a.shape(0)))
        throw py::value_error("sky: not an array sky_texture() returned (bad header or length)");
    auto sky = std::make_shared<SkyTexture>();
    std::memcpy(static_cast<void*>(&sky->params), a.data(), sizeof(SkyParams));
    sky->image.assign(a.data() + kSkyParamFloats, a.data() + a.shape(0));
    return sky;
}

void read_rotation(const py::handle& obj, float r[9]) {
    FloatArray a = FloatArray::ensure(obj);
    if (!a || a.ndim() != 2 || a.shape(0) != 3 || a.shape(1) != 3)
        throw py::value_error("rotation: expected a 3x3 float array");
    std::memcpy(r, a.data(), 9 * sizeof(float));
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            float d = 0.0f;
            for (int k = 0; k < 3; ++k) d += r[3 * i + k] * r[3 * j + k];
            if (!(std::fabs(d - (i == j ? 1.0f : 0.0f)) < 1e-3f))
                throw py::value_error("rotation: expected an orthonormal 3x3 rotation matrix");
        }
}

void set_world_sky(PyScene& self, const py::handle& packed, const py::handle& rotation) {
    self.check_mutable("set_world_sky");
    std::shared_ptr<const SkyTexture> sky = unpack(packed);
    float r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (!rotation.is_none()) read_rotation(rotation, r);
    EnvironmentMap map;
    {
        py::gil_scoped_release unlocked;
        map = make_sky_environment(std::move(sky), r);
    }
    self.scene.world_map = std::move(map);
    self.finalized = false;
}

py::array_t<float> world_radiance(const PyScene& self, const py::handle& directions) {
    FloatArray d = FloatArray::ensure(directions);
    if (!d || d.ndim() != 2 || d.shape(1) != 3) throw py::value_error("directions: expected a float array (N, 3)");
    const size_t n = size_t(d.shape(0));
    py::array_t<float> out({py::ssize_t(n), py::ssize_t(3)});
    float* o = out.mutable_data();
    const float* in = d.data();
    const Scene& scene = self.scene;
    py::gil_scoped_release unlocked;
    const bool has_map = !scene.world_map.empty();
    const EnvironmentSampler sampler = has_map ? EnvironmentSampler(scene.world_map) : EnvironmentSampler();
    for (size_t i = 0; i < n; ++i) {
        const Vec3f v{in[3 * i], in[3 * i + 1], in[3 * i + 2]};
        const float len = length(v);
        Vec3f c = scene.world_color;
        if (has_map) c = sampler.empty() || !(len > 0.0f) ? Vec3f(0.0f) : scene.world_color * sampler.eval(v / len);
        for (int k = 0; k < 3; ++k) o[3 * i + size_t(k)] = c[k];
    }
    return out;
}

}  // namespace

void bind_sky(py::module_& m) {
    const SkyInputs defaults;
    m.def("sky_texture", &sky_texture, py::arg("sky_type"), py::kw_only(),
          py::arg("sun_direction") = py::make_tuple(0.0f, 0.0f, 1.0f), py::arg("turbidity") = defaults.turbidity,
          py::arg("ground_albedo") = defaults.ground_albedo, py::arg("sun_disc") = defaults.sun_disc,
          py::arg("sun_size") = defaults.sun_size, py::arg("sun_intensity") = defaults.sun_intensity,
          py::arg("sun_elevation") = defaults.sun_elevation, py::arg("sun_rotation") = defaults.sun_rotation,
          py::arg("altitude") = defaults.altitude, py::arg("air_density") = defaults.air_density,
          py::arg("dust_density") = defaults.dust_density, py::arg("ozone_density") = defaults.ozone_density,
          R"doc(Precomputes Blender's Sky Texture (sky_type 'PREETHAM', 'HOSEK_WILKIE' or 'NISHITA'; the
node's settings by their Blender names, angles in radians, altitude in metres) as Cycles 3.4 does, into
the flat float32 array that Scene.set_world_sky and a shader program's SkyTexture instruction take.)doc");
    auto scene = py::reinterpret_borrow<py::class_<PyScene>>(m.attr("Scene"));
    scene.def("set_world_sky", &set_world_sky, py::arg("sky"), py::arg("rotation") = py::none(),
              "Makes the world a Sky Texture (the array sky_texture() returns): world radiance = world_color x "
              "sky(R d), R (3x3, default identity) taking world directions to the sky's frame; importance-"
              "sampled through a bake of the sky. clear_world_map() goes back to the constant colour.");
    scene.def("world_radiance", &world_radiance, py::arg("directions"),
              "World radiance (N, 3) towards world directions (N, 3), as camera rays that miss everything see it.");
}

}  // namespace coherent::python
