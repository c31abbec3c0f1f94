// Helpers for the glTF tests: a tiny writer of .gltf files with an embedded
// (base64) or external buffer, so each test states its input explicitly.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace coherent::test {

inline std::string base64(const std::string& bytes) {
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8 | uint8_t(bytes[i + 2]);
        for (int k = 3; k >= 0; --k) out += table[(v >> (6 * k)) & 63];
    }
    if (i + 1 == bytes.size()) {
        const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
        out += table[(v >> 18) & 63];
        out += table[(v >> 12) & 63];
        out += "==";
    } else if (i + 2 == bytes.size()) {
        const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8;
        out += table[(v >> 18) & 63];
        out += table[(v >> 12) & 63];
        out += table[(v >> 6) & 63];
        out += '=';
    }
    return out;
}

// Builds a glTF document with one buffer. Each add_* appends tightly packed
// data to the buffer with its own buffer view and accessor.
struct GltfBuilder {
    nlohmann::json doc;
    std::string bin;

    GltfBuilder() {
        doc["asset"] = {{"version", "2.0"}};
        doc["bufferViews"] = nlohmann::json::array();
        doc["accessors"] = nlohmann::json::array();
    }

    int add_view(const void* data, size_t bytes) {
        while (bin.size() % 4) bin.push_back('\0');
        const size_t offset = bin.size();
        bin.append(static_cast<const char*>(data), bytes);
        doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}});
        return int(doc["bufferViews"].size() - 1);
    }
    int add_accessor(int view, int component_type, size_t count, const char* type) {
        doc["accessors"].push_back({{"bufferView", view}, {"componentType", component_type}, {"count", count}, {"type", type}});
        return int(doc["accessors"].size() - 1);
    }
    int add_vec3(const std::vector<float>& v) {
        return add_accessor(add_view(v.data(), v.size() * 4), 5126, v.size() / 3, "VEC3");
    }
    int add_indices_u16(const std::vector<uint16_t>& v) {
        return add_accessor(add_view(v.data(), v.size() * 2), 5123, v.size(), "SCALAR");
    }
    int add_indices_u32(const std::vector<uint32_t>& v) {
        return add_accessor(add_view(v.data(), v.size() * 4), 5125, v.size(), "SCALAR");
    }
    int add_indices_u8(const std::vector<uint8_t>& v) {
        return add_accessor(add_view(v.data(), v.size()), 5121, v.size(), "SCALAR");
    }

    // Writes `dir/name` (.gltf); with `external`, the buffer goes to a .bin beside it.
    std::string write(const std::filesystem::path& dir, const std::string& name, bool external = false) {
        nlohmann::json d = doc;
        if (external) {
            const std::string bin_name = name + ".bin";
            std::ofstream(dir / bin_name, std::ios::binary) << bin;
            d["buffers"] = {{{"byteLength", bin.size()}, {"uri", bin_name}}};
        } else {
            d["buffers"] = {{{"byteLength", bin.size()},
                             {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
        }
        const auto path = dir / name;
        std::ofstream(path) << d.dump();
        return path.string();
    }
};

// A fresh directory under the system temp dir, removed by the destructor.
struct TempDir {
    std::filesystem::path path;
    TempDir() {
        std::random_device rd;
        path = std::filesystem::temp_directory_path() / ("coherent_test_" + std::to_string(rd()) + std::to_string(rd()));
        std::filesystem::create_directories(path);
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    std::string file(const std::string& name, const std::string& contents) const {
        std::ofstream(path / name, std::ios::binary) << contents;
        return (path / name).string();
    }
};

inline std::string read_bytes(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

}  // namespace coherent::test
