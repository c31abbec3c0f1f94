// A material's shader node graph as a small linear program (in the spirit of
// Cycles' SVM): the add-on compiles the node tree (addon/coherent/
// shader_compiler.py) into instructions over a register file of floats, and
// the renderer runs it once per shading point (shader/eval.h) to get the
// closure parameters of that point.
//
// Layout and invariants (checked by ShaderProgram::validate(), so a program
// that passed it can be run without bounds checks):
//  - Registers are floats; a vec3 (colour, vector, normal) is three
//    consecutive registers. `constants` initialises the whole register file
//    (so a constant input is just a register that no instruction writes).
//  - Instructions run in order; an instruction reads registers written by
//    earlier instructions or constants, and writes its outputs. There are no
//    jumps: node graphs are DAGs, the compiler orders them topologically.
//  - Every register index an instruction or output names, plus the width of
//    what it reads or writes there, lies inside the register file.
//  - `data` holds tables an instruction addresses by offset (ColorRamp's
//    256 RGBA entries, ...).
//  - `outputs` bind registers to closure parameters of the material's
//    constant template (Material::closures), which the program overrides.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace coherent {

// Register index meaning "not connected / not used".
constexpr uint16_t kNoRegister = 0xFFFF;
// The register file lives on the stack of the evaluating thread.
constexpr size_t kMaxShaderRegisters = 4096;
// Entries of a ColorRamp table (Cycles' RAMP_TABLE_SIZE).
constexpr int kRampTableSize = 256;

enum class ShaderOp : uint16_t {
    Math,         // mode: NodeMath type | kClampBit; in a, b, c (float); out0 float
    VectorMath,   // mode: NodeVectorMath type; in a, b, c (vec3), d (float scale); out0 vec3, out1 float
    MixColor,     // mode: blend | kClampFactorBit | kClampResultBit; in a fac, b, c (vec3); out0 vec3
    MixFloat,     // mode: kClampFactorBit; in a fac, b, c (float); out0 float
    MixVector,    // mode: kNonUniformBit | kClampFactorBit; in a fac (float or vec3), b, c; out0 vec3
    Mapping,      // mode: MappingType; in a vector, b location, c rotation, d scale; out0 vec3
    ColorRamp,    // mode: 1 = interpolate; data: table offset; in a fac; out0 vec3, out1 alpha
    Invert,       // in a fac, b colour; out0 vec3
    RgbToBw,      // in a colour; out0 float
    Combine,      // in a, b, c (float); out0 vec3
    Checker,      // in a vector, b colour1, c colour2, d scale; out0 colour, out1 fac
    ImageTexture, // mode: ImageFlags; data: scene image index; in a vector; out0 colour, out1 alpha
    TexCoord,     // mode: TexCoordKind; data: UV layer (for Uv); out0 vec3
    NormalMap,    // mode: NormalMapSpace; data: UV layer of the tangents; in a strength, b colour; out0 vec3
    Clamp,        // mode: 0 min-max, 1 range; in a value, b min, c max; out0 float
    // Procedural textures: registers through a list in `data`, modes and
    // layouts in shader/node_procedural.h.
    TexWhiteNoise,
    TexNoise,
    TexVoronoi,
    TexMusgrave,
    TexWave,
    TexGradient,
    TexMagic,
    TexBrick,
    // Colour adjustments, inputs and bump (formulas: node_adjust.h)
    Curves,               // mode: 1 = extrapolate; data: curve (min x, max x, 256 x RGBA); in a fac, b vec3; out0 vec3
    FloatCurve,           // mode: 1 = extrapolate; data: curve (min x, max x, 256 floats); in a fac, b value; out0 float
    HueSatVal,            // in a fac, b colour, c (hue, saturation, value); out0 vec3
    Gamma,                // in a colour, b gamma; out0 vec3
    BrightContrast,       // in a colour, b brightness, c contrast; out0 vec3
    MapRange,             // mode: MapRangeType; in a value, b from min, c from max, d (to min, to max, steps); out0 float
    VectorMapRangeFactor, // mode: MapRangeType; in a value, b from min, c from max, d steps (vec3); out0 factor vec3
    VectorMapRangeApply,  // mode: kClampBit; in a factor, b to min, c to max (vec3); out0 vec3
    ColorConvert,         // mode: ColorConversion; in a vec3; out0 vec3
    Fresnel,              // mode: FresnelKind; in a IOR or blend, b normal; out0 float
    Geometry,             // mode: GeometryKind | bump axis << 8; out0 vec3 (Backfacing: float)
    LightPath,            // mode: LightPathKind; out0 float (ShadingGeometry::path; 0 without one)
    Attribute,            // mode: bump axis; data: colour attribute (SceneShading::color_names); out0 colour, out1 alpha
    BumpTexCoord,         // mode: TexCoordKind | bump axis << 8; data: UV layer; out0 vec3 (TexCoord at a bump offset)
    Bump,                 // mode: 1 = invert; in a strength, b distance, c normal, d heights (centre, +dx, +dy); out0 vec3
    // Sky
    SkyTexture,   // data: offset of a packed sky (sky_model.h pack()); in a vector; out0 colour
    Count
};

constexpr uint16_t kClampBit = 0x100;
constexpr uint16_t kClampFactorBit = 0x100;
constexpr uint16_t kClampResultBit = 0x200;
constexpr uint16_t kNonUniformBit = 0x400;

enum class MappingType : uint16_t { Point = 0, Texture = 1, Vector = 2, Normal = 3 };
enum class TexCoordKind : uint16_t { Uv = 0, Generated = 1, Object = 2, Normal = 3, Position = 4, Incoming = 5 };
enum class NormalMapSpace : uint16_t { Tangent = 0, Object = 1, World = 2 };
// Outputs of the Geometry node (Geometry's mode).
enum class GeometryKind : uint16_t { Position, Normal, Tangent, TrueNormal, Incoming, Parametric, Backfacing, Count };
// Outputs of the Light Path node (LightPath's mode): ray-type tests, then lengths and depths.
enum class LightPathKind : uint16_t {
    IsCamera, IsShadow, IsDiffuse, IsGlossy, IsSingular, IsReflection, IsTransmission, RayLength, RayDepth,
    DiffuseDepth, GlossyDepth, TransparentDepth, TransmissionDepth, Count
};
// Bump offsets (Geometry, Attribute, BumpTexCoord): 0 the shading point, 1 and 2
// one footprint along Cycles' dP.dx and dP.dy, where Bump evaluates the height again.
constexpr int kBumpAxisShift = 8;
// Curve tables in `data` (Curves, FloatCurve): 2 floats of x range, then the entries.
constexpr int kCurveTableSize = 256;

// Image Texture flags (ImageTexture's mode).
enum ImageFlags : uint16_t {
    kImageInterpMask = 0x3,       // 0 linear, 1 closest, 2 cubic (3 smart = cubic)
    kImageExtensionShift = 2,     // 0 repeat, 1 extend, 2 clip
    kImageExtensionMask = 0xC,
    kImageSrgb = 0x10,            // colours are sRGB-encoded: decode after filtering, as Cycles does for bytes
    kImageUnassociate = 0x20,     // divide the colour by alpha after filtering (associated texels, Alpha used)
    kImagePremultiply = 0x40,     // multiply the filtered colour by alpha (glTF import only: the Blender
                                  // add-on associates straight texels before filtering, as Cycles does)
    kImageIgnoreAlpha = 0x80,     // alpha mode None: alpha is 1
    kImageBytes = 0x100,          // with kImagePremultiply: truncate the associated colour to 8 bits
};

// Closure parameters a program can drive. Vec3 fields read three registers.
enum class ShaderField : uint8_t {
    BaseColor,     // vec3, closure `closure`
    Metallic,
    Roughness,
    Specular,
    Transmission,
    Ior,
    Weight,        // the closure's weight in the material's sum
    Emission,      // vec3: emitted radiance (colour x strength, summed)
    Normal,        // vec3: world-space shading normal (from Normal Map), replaces the interpolated one
    Count
};
constexpr bool is_vec3_field(ShaderField f) {
    return f == ShaderField::BaseColor || f == ShaderField::Emission || f == ShaderField::Normal;
}

struct ShaderInstr {
    ShaderOp op = ShaderOp::Math;
    uint16_t mode = 0;
    uint16_t out[2] = {kNoRegister, kNoRegister};
    uint16_t in[4] = {kNoRegister, kNoRegister, kNoRegister, kNoRegister};
    uint32_t data = 0;
};

struct ShaderOutput {
    ShaderField field = ShaderField::BaseColor;
    uint8_t closure = 0;
    uint16_t reg = kNoRegister;
};

struct ShaderProgram {
    std::vector<ShaderInstr> code;
    std::vector<float> constants;  // the initial register file; its size is the register count
    std::vector<float> data;       // tables addressed by instructions
    std::vector<ShaderOutput> outputs;
    // What the program reads, so export and shading simulate only that.
    bool uses_uv = false, uses_tangents = false, uses_object_space = false;
    bool drives_emission = false, drives_normal = false;
    bool uses_light_path = false;  // a LightPath instruction: shading fills ShadingGeometry::path
    bool uses_bump = false;        // a Bump instruction: shading fills ShadingGeometry::footprint

    // Empty when the invariants above hold, else what is wrong (for an
    // error that names the material). `image_count`: images in the scene,
    // `uv_layer_count`: UV layers in the scene.
    std::string validate(size_t image_count, size_t uv_layer_count) const;
};

}  // namespace coherent
