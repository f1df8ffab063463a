// SPDX-License-Identifier: Apache-2.0
// The glTF reader's hard cases: each bad asset is refused with a SceneError that names the file, the
// JSON path (or the GLB byte) and what is allowed, before anything is read out of bounds or
// allocated without bound.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <functional>
#include <string>

#include "gltf_test_assets.h"
#include "scene/gltf/gltf_reader.h"

namespace fs = std::filesystem;
using namespace fovea::render;
using namespace fovea::test;

namespace {

std::string error_of(const std::function<void()>& read) {
  try {
    read();
  } catch (const SceneError& e) {
    return e.what();
  }
  return "(no error)";
}

#define EXPECT_CONTAINS(text, part) EXPECT_NE((text).find(part), std::string::npos) << (text)

// The error of reading `doc` with `bin` as bad.glb (beside an empty cube.png).
std::string glb_error(const GltfJson& doc, const GltfBin& bin, const gltf::ReadOptions& options = {}) {
  TempDir dir;
  write_file(dir.path / "cube.png", "");
  write_file(dir.path / "bad.glb", glb_bytes(doc, bin));
  return error_of([&] { (void)gltf::read_gltf(dir.path / "bad.glb", options); });
}
std::string glb_error(const GltfJson& doc) { return glb_error(doc, GltfCube().bin()); }

// The error of reading the cube as <dir>/asset/bad.gltf with its buffer at `uri`.
std::string uri_error(const TempDir& dir, const std::string& uri) {
  const GltfCube cube;
  const GltfBin bin = cube.bin();
  GltfJson doc = cube.doc();
  doc["buffers"] = GltfJson::array({{{"uri", uri}, {"byteLength", bin.bytes.size()}}});
  doc["bufferViews"] = bin.views;
  fs::create_directories(dir.path / "asset");
  write_file(dir.path / "asset" / "bad.gltf", doc.dump());
  return error_of([&] { (void)gltf::read_gltf(dir.path / "asset" / "bad.gltf"); });
}

TEST(GltfReaderErrors, AccessorPastItsBufferView) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][0]["count"] = 25;
  EXPECT_CONTAINS(glb_error(doc), "bad.glb: $.accessors[0]: 25 VEC3 float elements from byte 0 pass the end of bufferView 0 (288 bytes)");
}

TEST(GltfReaderErrors, BufferViewPastItsBuffer) {
  GltfBin bin = GltfCube().bin();
  bin.views[3]["byteLength"] = 100;
  EXPECT_CONTAINS(glb_error(GltfCube().doc(), bin), "$.bufferViews[3]: 100 bytes from byte 768 pass the end of buffer 0 (840 bytes)");
}

TEST(GltfReaderErrors, IndexPastTheVertexCount) {
  GltfCube cube;
  cube.indices[5] = 24;
  EXPECT_CONTAINS(glb_error(cube.doc(), cube.bin()),
                  "$.meshes[0].primitives[0].indices = 3: index 24 (element 5 of accessor 3) is not below the vertex count 24");
}

TEST(GltfReaderErrors, BadByteStride) {
  GltfBin bin = GltfCube().bin();
  bin.views[0]["byteStride"] = 6;
  EXPECT_CONTAINS(glb_error(GltfCube().doc(), bin), "$.bufferViews[0].byteStride = 6: must be a multiple of 4 in 4..252");
  bin.views[0]["byteStride"] = 8;
  EXPECT_CONTAINS(glb_error(GltfCube().doc(), bin), "$.accessors[0]: bufferView 0 has byteStride 8, less than one VEC3 float element (12 bytes)");
  bin.views[0]["byteStride"] = 256;
  EXPECT_CONTAINS(glb_error(GltfCube().doc(), bin), "$.bufferViews[0].byteStride = 256");
}

TEST(GltfReaderErrors, WrongComponentTypeForPosition) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][0]["componentType"] = 5123;
  EXPECT_CONTAINS(glb_error(doc), "$.meshes[0].primitives[0].attributes.POSITION = 0: accessor 0 is VEC3 unsigned short; "
                                  "POSITION must be VEC3 float");
}

TEST(GltfReaderErrors, AttributeCountsDiffer) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][2]["count"] = 20;
  EXPECT_CONTAINS(glb_error(doc), "$.meshes[0].primitives[0].attributes.TEXCOORD_0 = 2: accessor 2 has 20 elements, POSITION has 24");
}

TEST(GltfReaderErrors, IndexIntoAMissingArray) {
  GltfJson doc = GltfCube().doc();
  doc["meshes"][0]["primitives"][0]["material"] = 5;
  EXPECT_CONTAINS(glb_error(doc), "$.meshes[0].primitives[0].material = 5: must be an index into $.materials (0..0)");
  doc = GltfCube().doc();
  doc["nodes"][0]["mesh"] = -1;
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[0].mesh = -1: must be an index into $.meshes (0..0)");
}

TEST(GltfReaderErrors, BufferUriClimbingOutOfTheFolder) {
  TempDir dir;
  EXPECT_CONTAINS(uri_error(dir, "../../etc/passwd"), "bad.gltf: $.buffers[0].uri = \"../../etc/passwd\": outside the asset's folder");
  EXPECT_CONTAINS(uri_error(dir, "sub/%2E%2E/../x.bin"), "$.buffers[0].uri = \"sub/%2E%2E/../x.bin\": outside the asset's folder");
}

TEST(GltfReaderErrors, AbsoluteUriAndSchemes) {
  TempDir dir;
  EXPECT_CONTAINS(uri_error(dir, "/etc/passwd"), "$.buffers[0].uri = \"/etc/passwd\": an absolute path");
  EXPECT_CONTAINS(uri_error(dir, "%2Fetc%2Fpasswd"), "$.buffers[0].uri = \"%2Fetc%2Fpasswd\": an absolute path");
  EXPECT_CONTAINS(uri_error(dir, "file:///etc/passwd"), "$.buffers[0].uri = \"file:///etc/passwd\": a URI with a scheme");
  EXPECT_CONTAINS(uri_error(dir, "a%zz.bin"), "bad percent-encoding");
}

TEST(GltfReaderErrors, SymlinkOutOfTheFolder) {
  TempDir dir;
  fs::create_directories(dir.path / "outside");
  fs::create_directories(dir.path / "asset");
  write_file(dir.path / "outside" / "secret.bin", std::string(840, 'x'));
  fs::create_symlink(dir.path / "outside" / "secret.bin", dir.path / "asset" / "link.bin");
  EXPECT_CONTAINS(uri_error(dir, "link.bin"), "$.buffers[0].uri = \"link.bin\": leads outside the asset's folder");
  // A link that stays inside the folder is fine.
  const GltfBin bin = GltfCube().bin();
  write_file(dir.path / "asset" / "real.bin", std::string(bin.bytes.begin(), bin.bytes.end()));
  fs::create_symlink("real.bin", dir.path / "asset" / "inner.bin");
  EXPECT_EQ(uri_error(dir, "inner.bin"), "(no error)");
}

TEST(GltfReaderErrors, OversizedDataUri) {
  TempDir dir;
  const GltfCube cube;
  const fs::path file = write_gltf_data_uri(dir.path, "bad", cube.doc(), cube.bin());
  gltf::ReadOptions options;
  options.max_data_uri_bytes = 100;
  EXPECT_CONTAINS(error_of([&] { (void)gltf::read_gltf(file, options); }),
                  "bad.gltf: $.buffers[0].uri: a data: URI of 840 bytes, more than the limit of 100 (ReadOptions::max_data_uri_bytes)");
}

TEST(GltfReaderErrors, TruncatedAndBadGlb) {
  const GltfCube cube;
  const std::string glb = glb_bytes(cube.doc(), cube.bin());
  const auto error = [](const std::string& bytes) {
    return error_of([&] { (void)gltf::read_gltf_bytes(bytes, "bad.glb", {}); });
  };
  EXPECT_CONTAINS(error(glb.substr(0, glb.size() - 4)), "bad.glb: GLB byte 8: the header gives a length of");
  std::string cut = glb.substr(0, glb.size() - 4);
  const auto n = static_cast<std::uint32_t>(cut.size());
  cut.replace(8, 4, reinterpret_cast<const char*>(&n), 4);
  EXPECT_CONTAINS(error(cut), "GLB byte");
  EXPECT_CONTAINS(error(cut), "passes the end of the file");
  EXPECT_CONTAINS(error(glb.substr(0, 7)), "bad.glb: GLB byte 0: a GLB file starts with a 12-byte header");
  std::string magic = glb;
  magic[3] = 'X';
  EXPECT_CONTAINS(error(magic), "bad.glb: GLB byte 0: bad magic");
  std::string version = glb;
  version[4] = 1;
  EXPECT_CONTAINS(error(version), "bad.glb: GLB byte 4: GLB version 1");
}

TEST(GltfReaderErrors, NodeCycleAndTwoParents) {
  GltfJson doc = GltfCube().doc();
  doc["nodes"] = GltfJson::parse(R"([{"mesh": 0}, {"children": [2]}, {"children": [1]}])");
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[2].children: the node graph has a cycle");
  doc["nodes"] = GltfJson::parse(R"([{"mesh": 0, "children": [0]}])");
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[0].children[0] = 0: node 0 cannot be its own child");
  doc["nodes"] = GltfJson::parse(R"([{"children": [2]}, {"children": [2]}, {"mesh": 0}])");
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[1].children[0] = 2: node 2 is already a child of node 0; a node has at most one parent");
  doc["nodes"] = GltfJson::parse(R"([{"children": [1]}, {"mesh": 0}])");
  doc["scenes"] = GltfJson::parse(R"([{"nodes": [0, 1]}])");
  EXPECT_CONTAINS(glb_error(doc), "$.scenes[0].nodes[1] = 1: node 1 is a child of another node");
}

TEST(GltfReaderErrors, UnsupportedRequiredExtensionAndVersions) {
  GltfJson doc = GltfCube().doc();
  doc["extensionsRequired"] = {"KHR_lights_punctual", "KHR_draco_mesh_compression"};
  EXPECT_CONTAINS(glb_error(doc), "$.extensionsRequired[1] = \"KHR_draco_mesh_compression\": the asset requires extension "
                                  "KHR_draco_mesh_compression, which this reader does not support");
  doc = GltfCube().doc();
  doc["asset"]["version"] = "1.0";
  EXPECT_CONTAINS(glb_error(doc), "bad.glb: $.asset.version = \"1.0\": unsupported glTF version; this reader reads glTF 2.x");
  doc["asset"]["version"] = "2.1";
  doc["asset"]["minVersion"] = "2.1";
  EXPECT_CONTAINS(glb_error(doc), "$.asset.minVersion = \"2.1\": this reader supports glTF 2.0 only");
  doc.erase("asset");
  EXPECT_CONTAINS(glb_error(doc), "$.asset: missing required field");
}

TEST(GltfReaderErrors, NonFiniteMatrix) {
  GltfJson doc = GltfCube().doc();
  doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, "NaN", 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[0].matrix[5] = \"NaN\": must be a finite number");
  doc["nodes"][0]["matrix"][5] = 12345;
  std::string text = doc.dump();
  text.replace(text.find("12345"), 5, "1e999");
  EXPECT_CONTAINS(error_of([&] { (void)gltf::read_gltf_bytes(text, "bad.gltf", {}); }),
                  "bad.gltf: $.nodes[0].matrix[5] = 1e999: number overflows a double");
  doc["nodes"][0]["matrix"][5] = 1;
  doc["nodes"][0]["translation"] = {0, 0, 0};
  EXPECT_CONTAINS(glb_error(doc), "$.nodes[0].matrix: a node has either a matrix or translation, rotation and scale");
}

TEST(GltfReaderErrors, CountOfFourBillionIsRefusedBeforeAllocating) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][0]["count"] = 4000000000u;
  EXPECT_CONTAINS(glb_error(doc), "$.accessors[0]: 4000000000 VEC3 float elements from byte 0 pass the end of bufferView 0");
  doc["accessors"][0].erase("bufferView");  // all zeros: nothing to bound it but the budget
  EXPECT_CONTAINS(glb_error(doc), "$.meshes[0].primitives[0].attributes.POSITION = 0: accessor 0's 4000000000 elements would "
                                  "take 48000000000 bytes, past the asset's budget");
}

TEST(GltfReaderErrors, SparseAccessorsAndThirdTexcoordsAreRefused) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][0]["sparse"] = {{"count", 1}};
  EXPECT_CONTAINS(glb_error(doc), "$.accessors[0].sparse: sparse accessors are not supported by this reader");
  doc = GltfCube().doc();
  doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 2;
  EXPECT_CONTAINS(glb_error(doc), "$.materials[0].pbrMetallicRoughness.baseColorTexture.texCoord = 2: must be 0 or 1");
}

TEST(GltfReaderErrors, FactorsOutOfRange) {
  GltfJson doc = GltfCube().doc();
  doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = {1, 1, 1.5, 1};
  EXPECT_CONTAINS(glb_error(doc), "$.materials[0].pbrMetallicRoughness.baseColorFactor[2] = 1.5: must be a finite number in [0, 1]");
  doc = GltfCube().doc();
  doc["materials"][0]["alphaMode"] = "CUTOUT";
  EXPECT_CONTAINS(glb_error(doc), "$.materials[0].alphaMode = \"CUTOUT\": must be OPAQUE, MASK or BLEND");
}

TEST(GltfReaderErrors, TrianglesNotAMultipleOfThree) {
  GltfJson doc = GltfCube().doc();
  doc["accessors"][3]["count"] = 35;
  EXPECT_CONTAINS(glb_error(doc), "$.meshes[0].primitives[0].indices = 3: 35 indices, not a multiple of 3");
}

}  // namespace
