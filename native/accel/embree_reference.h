// Embree 3 as a reference implementation: the same triangles in an Embree
// scene, for cross-checks (tests) and throughput comparisons (coherent-bench).
//
// Header-only and only usable where Embree is linked (COHERENT_HAVE_EMBREE):
// the engine library itself never depends on Embree.
#pragma once

#ifndef COHERENT_HAVE_EMBREE
#error "embree_reference.h needs Embree (COHERENT_HAVE_EMBREE)"
#endif

#include <embree3/rtcore.h>

#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "../core/ray.h"
#include "../core/vec.h"

namespace coherent {

class EmbreeReference {
public:
    // `config` is passed to rtcNewDevice, e.g. "threads=1".
    // `robust` sets RTC_SCENE_FLAG_ROBUST (Embree's watertight mode).
    EmbreeReference(const Vec3f* triangle_vertices, size_t triangle_count, const char* config = "threads=1",
                    bool robust = false, RTCBuildQuality quality = RTC_BUILD_QUALITY_HIGH) {
        device_ = rtcNewDevice(config);
        if (!device_) throw std::runtime_error("rtcNewDevice failed");
        const auto start = std::chrono::steady_clock::now();
        scene_ = rtcNewScene(device_);
        rtcSetSceneBuildQuality(scene_, quality);
        if (robust) rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
        if (triangle_count > 0) {
            RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
            rtcSetGeometryBuildQuality(geom, quality);
            // rtcSetNewGeometryBuffer pads the allocation for Embree's 16-byte vertex loads.
            auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                                 3 * sizeof(float), 3 * triangle_count));
            std::memcpy(v, triangle_vertices, 3 * triangle_count * sizeof(Vec3f));
            auto* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0,
                                                                       RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                                       triangle_count));
            for (size_t i = 0; i < 3 * triangle_count; ++i) idx[i] = static_cast<unsigned>(i);
            rtcCommitGeometry(geom);
            rtcAttachGeometry(scene_, geom);
            rtcReleaseGeometry(geom);
        }
        rtcCommitScene(scene_);
        build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (rtcGetDeviceError(device_) != RTC_ERROR_NONE) throw std::runtime_error("Embree scene build failed");
    }
    ~EmbreeReference() {
        if (scene_) rtcReleaseScene(scene_);
        if (device_) rtcReleaseDevice(device_);
    }
    EmbreeReference(const EmbreeReference&) = delete;
    EmbreeReference& operator=(const EmbreeReference&) = delete;

    // Includes the copy into Embree's buffers (cheap next to the build).
    double build_seconds() const { return build_seconds_; }

    static RTCRay to_rtc(const Ray& r) {
        RTCRay q;
        q.org_x = r.o.x; q.org_y = r.o.y; q.org_z = r.o.z;
        q.dir_x = r.d.x; q.dir_y = r.d.y; q.dir_z = r.d.z;
        q.tnear = r.tmin;
        q.tfar = r.tmax;
        q.time = 0.0f;
        q.mask = 0xffffffffu;
        q.id = 0;
        q.flags = 0;
        return q;
    }

    bool intersect(const Ray& r, Hit& hit) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh;
        rh.ray = to_rtc(r);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene_, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
        hit.t = rh.ray.tfar;
        hit.u = rh.hit.u;
        hit.v = rh.hit.v;
        hit.prim = rh.hit.primID;
        return true;
    }

    bool occluded(const Ray& r) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay q = to_rtc(r);
        rtcOccluded1(scene_, &ctx, &q);
        return q.tfar < 0.0f;  // Embree sets tfar = -inf on a hit
    }

    // Eight rays at once (rtcIntersect8): lanes with valid[i] == -1 are
    // traced, the others (valid[i] == 0) are ignored and their hits[i] left
    // as they are. `coherent` sets RTC_INTERSECT_CONTEXT_FLAG_COHERENT (the
    // rays come from one pixel block). Returns the mask of lanes that hit.
    int intersect8(const int* valid, const Ray* rays, Hit* hits, bool coherent = true) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        alignas(32) RTCRayHit8 rh;
        alignas(32) int v[8];
        for (int i = 0; i < 8; ++i) {
            v[i] = valid[i];
            fill8(rh.ray, i, valid[i] ? rays[i] : Ray{});
            rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
            rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
        }
        rtcIntersect8(v, scene_, &ctx, &rh);
        int mask = 0;
        for (int i = 0; i < 8; ++i) {
            if (!valid[i] || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
            hits[i] = Hit{rh.ray.tfar[i], rh.hit.u[i], rh.hit.v[i], rh.hit.primID[i]};
            mask |= 1 << i;
        }
        return mask;
    }

    // Eight occlusion rays (rtcOccluded8); returns the mask of occluded lanes.
    int occluded8(const int* valid, const Ray* rays, bool coherent = true) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
        alignas(32) RTCRay8 r;
        alignas(32) int v[8];
        for (int i = 0; i < 8; ++i) {
            v[i] = valid[i];
            fill8(r, i, valid[i] ? rays[i] : Ray{});
        }
        rtcOccluded8(v, scene_, &ctx, &r);
        int mask = 0;
        for (int i = 0; i < 8; ++i)
            if (valid[i] && r.tfar[i] < 0.0f) mask |= 1 << i;  // Embree sets tfar = -inf on a hit
        return mask;
    }

private:
    static void fill8(RTCRay8& q, int i, const Ray& r) {
        q.org_x[i] = r.o.x; q.org_y[i] = r.o.y; q.org_z[i] = r.o.z;
        q.dir_x[i] = r.d.x; q.dir_y[i] = r.d.y; q.dir_z[i] = r.d.z;
        q.tnear[i] = r.tmin;
        q.tfar[i] = r.tmax;
        q.time[i] = 0.0f;
        q.mask[i] = 0xffffffffu;
        q.id[i] = 0;
        q.flags[i] = 0;
    }

    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    double build_seconds_ = 0.0;
};

}  // namespace coherent
