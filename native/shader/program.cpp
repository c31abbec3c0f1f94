// ShaderProgram::validate(): the invariants of program.h, checked once when
// a program enters the scene so the interpreter needs no checks.
#include "program.h"

#include "node_adjust.h"
#include "node_color.h"
#include "node_math.h"
#include "node_procedural.h"
#include "sky_model.h"

namespace coherent {

namespace {

// Register widths an op reads (in[0..3]) and writes (out[0..1]); 0 = unused.
struct OpShape {
    int in[4];
    int out[2];
};

OpShape shape_of(const ShaderInstr& in) {
    switch (in.op) {
        case ShaderOp::Math: return {{1, 1, 1, 0}, {1, 0}};
        case ShaderOp::VectorMath: return {{3, 3, 3, 1}, {3, 1}};
        case ShaderOp::MixColor: return {{1, 3, 3, 0}, {3, 0}};
        case ShaderOp::MixFloat: return {{1, 1, 1, 0}, {1, 0}};
        case ShaderOp::MixVector: return {{(in.mode & kNonUniformBit) ? 3 : 1, 3, 3, 0}, {3, 0}};
        case ShaderOp::Mapping: return {{3, 3, 3, 3}, {3, 0}};
        case ShaderOp::ColorRamp: return {{1, 0, 0, 0}, {3, 1}};
        case ShaderOp::Invert: return {{1, 3, 0, 0}, {3, 0}};
        case ShaderOp::RgbToBw: return {{3, 0, 0, 0}, {1, 0}};
        case ShaderOp::Combine: return {{1, 1, 1, 0}, {3, 0}};
        case ShaderOp::Checker: return {{3, 3, 3, 1}, {3, 1}};
        case ShaderOp::ImageTexture: return {{3, 0, 0, 0}, {3, 1}};
        case ShaderOp::TexCoord: return {{0, 0, 0, 0}, {3, 0}};
        case ShaderOp::NormalMap: return {{1, 3, 0, 0}, {3, 0}};
        case ShaderOp::Clamp: return {{1, 1, 1, 0}, {1, 0}};
        // Procedural textures: no fixed slots, a register list in `data` (node_procedural.h).
        case ShaderOp::TexWhiteNoise:
        case ShaderOp::TexNoise:
        case ShaderOp::TexVoronoi:
        case ShaderOp::TexMusgrave:
        case ShaderOp::TexWave:
        case ShaderOp::TexGradient:
        case ShaderOp::TexMagic:
        case ShaderOp::TexBrick: break;
        // Colour adjustments, inputs and bump
        case ShaderOp::Curves: return {{1, 3, 0, 0}, {3, 0}};
        case ShaderOp::FloatCurve: return {{1, 1, 0, 0}, {1, 0}};
        case ShaderOp::HueSatVal: return {{1, 3, 3, 0}, {3, 0}};
        case ShaderOp::Gamma: return {{3, 1, 0, 0}, {3, 0}};
        case ShaderOp::BrightContrast: return {{3, 1, 1, 0}, {3, 0}};
        case ShaderOp::MapRange: return {{1, 1, 1, 3}, {1, 0}};
        case ShaderOp::VectorMapRangeFactor: return {{3, 3, 3, 3}, {3, 0}};
        case ShaderOp::VectorMapRangeApply: return {{3, 3, 3, 0}, {3, 0}};
        case ShaderOp::ColorConvert: return {{3, 0, 0, 0}, {3, 0}};
        case ShaderOp::Fresnel: return {{1, 3, 0, 0}, {1, 0}};
        case ShaderOp::Geometry: return {{0, 0, 0, 0}, {(in.mode & 0xFF) == uint16_t(GeometryKind::Backfacing) ? 1 : 3, 0}};
        case ShaderOp::LightPath: return {{0, 0, 0, 0}, {1, 0}};
        case ShaderOp::Attribute: return {{0, 0, 0, 0}, {3, 1}};
        case ShaderOp::BumpTexCoord: return {{0, 0, 0, 0}, {3, 0}};
        case ShaderOp::Bump: return {{1, 1, 3, 3}, {3, 0}};
        case ShaderOp::SkyTexture: return {{3, 0, 0, 0}, {3, 0}};
        case ShaderOp::Count: break;
    }
    return {{0, 0, 0, 0}, {0, 0}};
}

// The enum an op's mode selects must exist.
bool mode_valid(const ShaderInstr& in) {
    const uint16_t low = in.mode & 0xFF;
    switch (in.op) {
        case ShaderOp::Math: return low < uint16_t(shader::MathOp::Count);
        case ShaderOp::VectorMath: return in.mode < uint16_t(shader::VectorMathOp::Count);
        case ShaderOp::MixColor: return low < uint16_t(shader::MixBlend::Count);
        case ShaderOp::Mapping: return in.mode <= uint16_t(MappingType::Normal);
        case ShaderOp::TexCoord: return in.mode <= uint16_t(TexCoordKind::Incoming);
        case ShaderOp::NormalMap: return in.mode <= uint16_t(NormalMapSpace::World);
        case ShaderOp::ImageTexture: return ((in.mode & kImageExtensionMask) >> kImageExtensionShift) <= 2;
        case ShaderOp::Clamp: return in.mode <= 1;
        // Colour adjustments, inputs and bump
        case ShaderOp::Curves:
        case ShaderOp::FloatCurve: return in.mode <= 1;
        case ShaderOp::MapRange:
        case ShaderOp::VectorMapRangeFactor: return in.mode < uint16_t(shader::MapRangeType::Count);
        case ShaderOp::VectorMapRangeApply: return (in.mode & ~kClampBit) == 0;
        case ShaderOp::ColorConvert: return in.mode < uint16_t(shader::ColorConversion::Count);
        case ShaderOp::Fresnel: return in.mode < uint16_t(shader::FresnelKind::Count);
        case ShaderOp::Geometry: return low < uint16_t(GeometryKind::Count) && (in.mode >> kBumpAxisShift) <= 2;
        case ShaderOp::Attribute: return in.mode <= 2;
        case ShaderOp::BumpTexCoord:
            return low <= uint16_t(TexCoordKind::Incoming) && (in.mode >> kBumpAxisShift) <= 2;
        case ShaderOp::Bump: return in.mode <= 1;
        case ShaderOp::LightPath: return in.mode < uint16_t(LightPathKind::Count);
        default: return in.op < ShaderOp::Count;
    }
}

std::string where(size_t i) { return "instruction " + std::to_string(i) + ": "; }

}  // namespace

std::string ShaderProgram::validate(size_t image_count, size_t uv_layer_count) const {
    const size_t regs = constants.size();
    if (regs > kMaxShaderRegisters)
        return "uses " + std::to_string(regs) + " registers (at most " + std::to_string(kMaxShaderRegisters) + ")";
    auto fits = [&](uint16_t reg, int width) { return width == 0 || (reg != kNoRegister && reg + size_t(width) <= regs); };
    for (size_t i = 0; i < code.size(); ++i) {
        const ShaderInstr& in = code[i];
        if (in.op >= ShaderOp::Count || !mode_valid(in)) return where(i) + "unknown operation or mode";
        const OpShape s = shape_of(in);
        for (int k = 0; k < 4; ++k)
            if (!fits(in.in[k], s.in[k])) return where(i) + "input " + std::to_string(k) + " outside the registers";
        for (int k = 0; k < 2; ++k)
            if (in.out[k] != kNoRegister && !fits(in.out[k], s.out[k]))
                return where(i) + "output " + std::to_string(k) + " outside the registers";
        if (in.op == ShaderOp::ColorRamp && size_t(in.data) + 4 * kRampTableSize > data.size())
            return where(i) + "colour ramp table outside the data";
        const size_t curve_floats = in.op == ShaderOp::Curves ? 4 * kCurveTableSize : kCurveTableSize;
        if ((in.op == ShaderOp::Curves || in.op == ShaderOp::FloatCurve) &&
            size_t(in.data) + shader::kCurveHeader + curve_floats > data.size())
            return where(i) + "curve table outside the data";
        if (in.op == ShaderOp::ImageTexture && in.data >= image_count)
            return where(i) + "image " + std::to_string(in.data) + " does not exist";
        if ((in.op == ShaderOp::TexCoord || in.op == ShaderOp::BumpTexCoord) &&
            (in.mode & 0xFF) == uint16_t(TexCoordKind::Uv) && in.data >= uv_layer_count)
            return where(i) + "UV layer " + std::to_string(in.data) + " does not exist";
        if (is_procedural(in.op)) {
            const std::string error = validate_procedural(in, data, regs);
            if (!error.empty()) return where(i) + error;
        }
        if (in.op == ShaderOp::SkyTexture &&
            (in.data > data.size() || !packed_sky_valid(data.data() + in.data, data.size() - in.data)))
            return where(i) + "sky texture data missing or malformed";
    }
    for (size_t i = 0; i < outputs.size(); ++i) {
        const ShaderOutput& o = outputs[i];
        if (o.field >= ShaderField::Count || o.closure >= 4 || !fits(o.reg, is_vec3_field(o.field) ? 3 : 1))
            return "output " + std::to_string(i) + ": unknown field, closure or register";
    }
    return {};
}

}  // namespace coherent
