// Path kernels are templates over the few SceneFeatures bits that change
// which rays exist (path_tracer.h): glass lobes, lens sampling, lights
// (next-event estimation). Every driver instantiates all eight variants and
// picks one at run time, here.
#pragma once

#include <type_traits>

namespace coherent {

struct KernelFeatures {
    bool glass = false;
    bool depth_of_field = false;
    bool lights = false;
};

// make(std::bool_constant<glass>{}, std::bool_constant<depth_of_field>{},
// std::bool_constant<lights>{}) for the run-time bits of `f`: the caller's
// generic lambda names its kernel<G(), D(), L()>, and every combination is
// instantiated. All eight calls must return the same type (a function
// pointer).
template <class Make>
auto select_kernel_variant(const KernelFeatures& f, Make&& make) {
    auto with = [](bool bit, auto&& next) {
        return bit ? next(std::true_type{}) : next(std::false_type{});
    };
    return with(f.glass, [&](auto g) {
        return with(f.depth_of_field, [&](auto d) { return with(f.lights, [&](auto l) { return make(g, d, l); }); });
    });
}

}  // namespace coherent
