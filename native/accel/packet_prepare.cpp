// Preparing a packet for traversal (packet_kernels.h, PacketRays): each
// chunk of eight rays is loaded once and turned into the per-lane constants
// of the box and triangle tests, in the same arithmetic as the single-ray
// kernel's RayBoxConstants and WatertightRay (so every lane's results are
// bit-identical to Bvh::intersect's); the packet-wide choices (fused box
// test, one octant, interval bounds) are settled over the live lanes.
#include "packet_kernels.h"

namespace coherent::packet {

namespace {

// Chunk c of a packet as loaded, with its live lanes: active and valid.
// Lanes past the packet's size may hold anything (never read as rays): only
// blends on `live` let their bits through, as harmless constants.
struct ChunkInput {
    vfloat8 o[3], d[3], tmin, tmax;
    uint32_t live;
    vbool8 live_lanes;  // `live` as a lane mask
};

// Loads chunk c; live lanes: active, and valid in the sense of prepare().
ChunkInput load_chunk(const RayPacket& packet, int c, int size) {
    const int o = c * kPacketLanes;
    const int in_use = size - o >= kPacketLanes ? kPacketLanes : size - o;
    const uint32_t active = packet.chunk_mask(c) & ((1u << in_use) - 1u);
    ChunkInput in;
    const float* const src_o[3] = {packet.ox + o, packet.oy + o, packet.oz + o};
    const float* const src_d[3] = {packet.dx + o, packet.dy + o, packet.dz + o};
    for (int a = 0; a < 3; ++a) in.o[a] = vfloat8::load(src_o[a]), in.d[a] = vfloat8::load(src_d[a]);
    in.tmin = vfloat8::load(packet.tmin + o), in.tmax = vfloat8::load(packet.tmax + o);
    const vfloat8 zero = vfloat8::zero();
    vbool8 ok = (isfinite(in.o[0]) & isfinite(in.o[1])) & isfinite(in.o[2]);
    ok = ok & ((isfinite(in.d[0]) & isfinite(in.d[1])) & isfinite(in.d[2]));
    const vbool8 nonzero = ((in.d[0] != zero) | (in.d[1] != zero)) | (in.d[2] != zero);
    ok = (ok & nonzero) & (in.tmin <= in.tmax);
    in.live = active & static_cast<uint32_t>(movemask(ok));
    in.live_lanes = vbool8::from_bits(static_cast<int>(in.live));
    return in;
}

// Box-test constants of chunk c (dead lanes get a ray that enters nothing:
// no NaN, no denormal): origin, 1/d in `inv`, and the fused form's o/d
// rounded outward, exactly as the single-ray kernel's RayBoxConstants:
// |fl(o * inv) - o * inv| <= 2^-24 |fl(o * inv)| (1 + 2^-23); a margin of
// 2^-22 |e| + 2^-126 survives the rounding of the addition. Returns whether
// every live lane may use the fused form.
bool store_box_constants(const ChunkInput& in, float magnitude, PacketRays& r, int c, vfloat8 inv[3]) {
    const int o = c * kPacketLanes;
    const vfloat8 zero = vfloat8::zero(), one = 1.0f;
    const vbool8 lm = in.live_lanes;
    for (int a = 0; a < 3; ++a) inv[a] = select(lm, one / in.d[a], one);
    const vfloat8 org[3] = {select(lm, in.o[0], zero), select(lm, in.o[1], zero), select(lm, in.o[2], zero)};
    float* const out_o[3] = {r.ox + o, r.oy + o, r.oz + o};
    float* const out_inv[3] = {r.ix + o, r.iy + o, r.iz + o};
    float* const ch[3] = {r.chx + o, r.chy + o, r.chz + o};
    float* const cl[3] = {r.clx + o, r.cly + o, r.clz + o};
    bool fused = true;
    for (int a = 0; a < 3; ++a) {
        store(out_o[a], org[a]);
        store(out_inv[a], inv[a]);
        const vfloat8 e = org[a] * inv[a];
        const vfloat8 margin = abs(e) * vfloat8(0x1p-22f) + vfloat8(0x1p-126f);
        store(ch[a], e + margin);
        store(cl[a], e - margin);
        // |1/d| * max(|o|, magnitude, 1) <= 2^100 (fails for an infinite 1/d).
        const vfloat8 reach = abs(inv[a]) * max(max(abs(org[a]), vfloat8(magnitude)), one);
        if ((movemask(reach <= vfloat8(0x1p100f)) & in.live) != in.live) fused = false;
    }
    return fused;
}

// The closest-hit records of chunk c start at (t = tmax, no triangle); dead
// lanes get t = -1, which no box test passes.
void start_records(const ChunkInput& in, PacketRays& r, int c) {
    const int o = c * kPacketLanes;
    const vfloat8 zero = vfloat8::zero();
    store(r.tmin + o, select(in.live_lanes, in.tmin, zero));
    const vfloat8 best = select(in.live_lanes, in.tmax, vfloat8(-1.0f));
    store(r.best_t + o, best);
    store(r.cull + o, cull_distance(best));
    store(r.best_u + o, zero);
    store(r.best_v + o, zero);
    store(r.best_prim + o, vint8(-1));
}

// x, y or z per lane: where is0, x; else where is1, y; else z.
template <class V>
V pick(V x, V y, V z, vbool8 is0, vbool8 is1) {
    return select(is0, x, select(is1, y, z));
}
// Lane i of (x, y, z)[k[i]].
vfloat8 by_axis(const vfloat8 v[3], vint8 k) { return pick(v[0], v[1], v[2], k == vint8(0), k == vint8(1)); }

// Watertight constants of chunk c: WatertightRay's constructor (triangle.h)
// in SIMD, the same comparisons and the same products, hence the same floats
// as the single-ray kernel; then whether all live lanes share one
// permutation (r.perm[c]). Dead lanes get d = +z (kx, ky, kz = 0, 1, 2, no
// shear). `inv`: the chunk's 1/d (store_box_constants).
void store_watertight_constants(const ChunkInput& in, const vfloat8 inv[3], PacketRays& r, int c) {
    const int o = c * kPacketLanes;
    const vfloat8 zero = vfloat8::zero();
    const vbool8 lm = in.live_lanes;
    const vfloat8 d[3] = {select(lm, in.d[0], zero), select(lm, in.d[1], zero), select(lm, in.d[2], vfloat8(1.0f))};
    const vfloat8 org[3] = {select(lm, in.o[0], zero), select(lm, in.o[1], zero), select(lm, in.o[2], zero)};
    const vfloat8 adx = abs(d[0]), ady = abs(d[1]), adz = abs(d[2]);
    // max_dimension: ax > ay ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2).
    const vbool8 xy = adx > ady;
    const vbool8 kz0 = xy & (adx > adz);
    const vbool8 kz1 = andnot(ady > adz, xy);
    // kx, ky before the swap: kz 0 -> (1, 2), 1 -> (2, 0), 2 -> (0, 1);
    // swapped when d[kz] < 0.
    const vbool8 swap = pick(d[0], d[1], d[2], kz0, kz1) < zero;
    const vint8 kz = pick(vint8(0), vint8(1), vint8(2), kz0, kz1);
    const vint8 kx0 = pick(vint8(1), vint8(2), vint8(0), kz0, kz1);
    const vint8 ky0 = pick(vint8(2), vint8(0), vint8(1), kz0, kz1);
    const vint8 kx = select(swap, ky0, kx0), ky = select(swap, kx0, ky0);
    const vfloat8 sz = by_axis(inv, kz);
    store(r.kx + o, kx);
    store(r.ky + o, ky);
    store(r.kz + o, kz);
    store(r.sz + o, sz);
    store(r.sx + o, by_axis(d, kx) * sz);
    store(r.sy + o, by_axis(d, ky) * sz);
    store(r.okx + o, by_axis(org, kx));
    store(r.oky + o, by_axis(org, ky));
    store(r.okz + o, by_axis(org, kz));
    // One permutation for all live lanes?
    r.perm[c] = -1;
    if (!in.live) return;
    const vint8 perm = kx | ((ky << 2) | (kz << 4));
    const int l0 = o + __builtin_ctz(in.live);
    const int p0 = r.kx[l0] | r.ky[l0] << 2 | r.kz[l0] << 4;
    if ((movemask(perm == vint8(p0)) & in.live) == in.live) r.perm[c] = p0;
}

// Octant and interval bounds over a packet's live lanes, chunk by chunk.
struct LiveBounds {
    int any_neg = 0, any_pos = 0;  // per axis bits (1 = x, 2 = y, 4 = z)
    bool all_inv_finite = true;
    vfloat8 olo[3], ohi[3], ilo[3], ihi[3];
    vfloat8 tmin_lo = kInf;

    LiveBounds() {
        for (int a = 0; a < 3; ++a) olo[a] = ilo[a] = kInf, ohi[a] = ihi[a] = -kInf;
    }

    void add(const ChunkInput& in, const vfloat8 inv[3]) {
        const uint32_t live = in.live;
        const vbool8 lm = in.live_lanes;
        const vfloat8 inf = kInf, minus_inf = -kInf;
        for (int a = 0; a < 3; ++a) {
            const uint32_t neg = static_cast<uint32_t>(movemask(signbit(inv[a]))) & live;
            if (neg) any_neg |= 1 << a;
            if (live & ~neg) any_pos |= 1 << a;
            if ((movemask(isfinite(inv[a])) & live) != live) all_inv_finite = false;
            olo[a] = min(olo[a], select(lm, in.o[a], inf));
            ohi[a] = max(ohi[a], select(lm, in.o[a], minus_inf));
            ilo[a] = min(ilo[a], select(lm, inv[a], inf));
            ihi[a] = max(ihi[a], select(lm, inv[a], minus_inf));
        }
        tmin_lo = min(tmin_lo, select(lm, in.tmin, inf));
    }

    // The packet-wide choices: near planes, and the interval test's bounds
    // when all live rays share one octant and have finite 1/d.
    void finish(PacketRays& r) const {
        r.uniform_signs = (any_neg & any_pos) == 0;
        for (int a = 0; a < 3; ++a) r.near_hi[a] = (any_neg >> a) & 1;
        r.interval = r.uniform_signs && all_inv_finite;
        if (!r.interval) return;
        for (int a = 0; a < 3; ++a) {
            r.axis_o_lo[a] = reduce_min(olo[a]);
            r.axis_o_hi[a] = reduce_max(ohi[a]);
            r.axis_inv_lo[a] = reduce_min(ilo[a]);
            r.axis_inv_hi[a] = reduce_max(ihi[a]);
        }
        r.o_lo = vfloat4(r.axis_o_lo[0], r.axis_o_lo[1], r.axis_o_lo[2], 0.0f);
        r.o_hi = vfloat4(r.axis_o_hi[0], r.axis_o_hi[1], r.axis_o_hi[2], 0.0f);
        r.inv_lo = vfloat4(r.axis_inv_lo[0], r.axis_inv_lo[1], r.axis_inv_lo[2], 1.0f);
        r.inv_hi = vfloat4(r.axis_inv_hi[0], r.axis_inv_hi[1], r.axis_inv_hi[2], 1.0f);
        r.tmin_lo = reduce_min(tmin_lo);
        r.cull_hi = kInf;
    }
};

}  // namespace

bool prepare(const RayPacket& packet, float magnitude, PacketRays& r) {
    const int size = packet_size(packet);
    r.chunks = (size + kPacketLanes - 1) / kPacketLanes;
    r.first_chunk = r.chunks;
    bool fused = true;
    LiveBounds bounds;
    for (int c = 0; c < r.chunks; ++c) {
        const ChunkInput in = load_chunk(packet, c, size);
        r.live[c] = r.valid[c] = in.live;
        if (in.live && r.first_chunk == r.chunks) {
            r.first_chunk = c;
            const int l0 = c * kPacketLanes + __builtin_ctz(in.live);
            r.first_dir = Vec3f(packet.dx[l0], packet.dy[l0], packet.dz[l0]);
        }
        vfloat8 inv[3];
        if (!store_box_constants(in, magnitude, r, c, inv)) fused = false;
        start_records(in, r, c);
        store_watertight_constants(in, inv, r, c);
        bounds.add(in, inv);
    }
    if (r.first_chunk == r.chunks) return false;
    r.fused = fused;
    bounds.finish(r);
    return true;
}

}  // namespace coherent::packet
