// The damage every model image must survive, for each kind (modal shell, tet tensor,
// catheter) through the same helpers (image_test_support.hpp): every header field broken on its
// own is refused with its own message before anything else is read, and a byte flipped in each
// section is refused by the checksum. Messages start with the file's path.
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "image_test_support.hpp"
#include "trainer/core/arena.hpp"
#include "trainer/model/image_loader.hpp"

namespace trainer::model {
namespace {

struct KindImage {
  ModelKind kind;
  std::vector<std::byte> (*bytes)();
};

class ImageDamage : public ::testing::TestWithParam<KindImage> {
 protected:
  core::Expected<ModelImage> load(const std::vector<std::byte>& bytes) {
    test::write_file(file(), bytes);
    arena_.reset();
    arena_.emplace(core::Arena::create(64 * 1024).value());
    return load_model_image(file(), *arena_, ImageLimits{}, GetParam().kind);
  }
  std::filesystem::path file() const { return directory_.path() / "model.img"; }

  test::TemporaryDirectory directory_;
  std::optional<core::Arena> arena_;
};

TEST_P(ImageDamage, TheUndamagedImageLoads) {
  auto loaded = load(GetParam().bytes());
  ASSERT_TRUE(loaded) << loaded.error().message;
  EXPECT_EQ(loaded.value().model_kind(), GetParam().kind);
}

TEST_P(ImageDamage, EveryHeaderFieldBrokenIsRefusedWithItsOwnMessage) {
  const std::vector<std::byte> original = GetParam().bytes();
  const std::vector<test::HeaderMutation> mutations =
      test::header_mutations(GetParam().kind, original.size());
  EXPECT_EQ(mutations.size(), 14U);
  for (const test::HeaderMutation& mutation : mutations) {
    EXPECT_TRUE(test::failed_with(load(test::mutated(original, mutation)), file().string(),
                                  mutation.fragment))
        << mutation.field;
    if (mutation.recompute_checksum) {
      // Refused from the header alone: no arena space reserved (the checksum needs the bytes).
      EXPECT_EQ(arena_->used_bytes(), mutation.field == "reserved" ? original.size() : 0U)
          << mutation.field;
    }
  }
}

TEST_P(ImageDamage, AByteFlippedInEachSectionIsRefusedByTheChecksum) {
  const std::vector<std::byte> original = GetParam().bytes();
  const auto middles = test::section_middle_bytes(original);
  ASSERT_GE(middles.size(), 3U);
  for (const auto& [id, position] : middles) {
    std::vector<std::byte> bytes = original;
    bytes[position] ^= std::byte{0x40};
    EXPECT_TRUE(test::failed_with(load(bytes), file().string(), "checksum mismatch"))
        << section_name(id);
  }
}

INSTANTIATE_TEST_SUITE_P(
    EveryKind, ImageDamage,
    ::testing::Values(
        KindImage{ModelKind::modal_shell, [] { return test::SmallModalShell().bytes(); }},
        KindImage{ModelKind::tet_tensor, [] { return test::SmallTetTensor().bytes(); }},
        KindImage{ModelKind::catheter, [] { return test::SmallCatheter().bytes(); }}),
    [](const ::testing::TestParamInfo<KindImage>& param) {
      return std::string(model_kind_name(param.param.kind));
    });

}  // namespace
}  // namespace trainer::model
