// CompositeDevice: the lifecycle order that keeps drive power behind a claimed, inactive
// drive-enable line (I/O configured and activated before the motion, deactivated after it),
// failures unwinding, the interfaces routed to the right part.
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "trainer/hal/composite_device.hpp"

namespace trainer::hal {
namespace {

class RecordingDevice final : public Device, public EncoderInterface, public DigitalInputInterface {
 public:
  RecordingDevice(std::string name, std::vector<std::string>& journal)
      : name_(std::move(name)), journal_(journal) {}
  std::string_view name() const noexcept override { return name_; }
  core::Expected<void> configure() override {
    journal_.push_back(name_ + " configure");
    if (fail_configure) return core::make_error(name_ + " configure failed");
    state_ = LifecycleState::inactive;
    return {};
  }
  core::Expected<void> activate() override {
    journal_.push_back(name_ + " activate");
    if (fail_activate) return core::make_error(name_ + " activate failed");
    state_ = LifecycleState::active;
    return {};
  }
  void deactivate() noexcept override {
    journal_.push_back(name_ + " deactivate");
    if (state_ == LifecycleState::active) state_ = LifecycleState::inactive;
  }
  LifecycleState state() const noexcept override { return state_; }
  EncoderInterface* encoders() noexcept override { return this; }
  DigitalInputInterface* digital_inputs() noexcept override { return this; }
  std::size_t encoder_count() const noexcept override { return 0; }
  ReturnCode read_encoders(std::span<EncoderSample>) noexcept override { return ReturnCode::ok; }
  std::size_t digital_input_count() const noexcept override { return 0; }
  ReturnCode read_digital_inputs(std::uint32_t&) noexcept override { return ReturnCode::ok; }

  bool fail_configure = false;
  bool fail_activate = false;

 private:
  std::string name_;
  std::vector<std::string>& journal_;
  LifecycleState state_ = LifecycleState::unconfigured;
};

struct Parts {
  std::vector<std::string> journal;
  RecordingDevice* motion = nullptr;
  RecordingDevice* io = nullptr;
  std::unique_ptr<CompositeDevice> device;
  Parts() {
    auto m = std::make_unique<RecordingDevice>("motion", journal);
    auto i = std::make_unique<RecordingDevice>("io", journal);
    motion = m.get();
    io = i.get();
    device = std::make_unique<CompositeDevice>("both", std::move(m), std::move(i));
  }
};

TEST(CompositeDevice, IoFirstUpMotionFirstDown) {
  Parts parts;
  ASSERT_TRUE(parts.device->configure());
  EXPECT_EQ(parts.device->state(), LifecycleState::inactive);
  ASSERT_TRUE(parts.device->activate());
  EXPECT_EQ(parts.device->state(), LifecycleState::active);
  parts.device->deactivate();
  EXPECT_EQ(parts.journal,
            (std::vector<std::string>{"io configure", "motion configure", "io activate",
                                      "motion activate", "motion deactivate", "io deactivate"}));
}

TEST(CompositeDevice, MotionFailureReleasesTheLines) {
  Parts parts;
  parts.motion->fail_configure = true;
  auto configured = parts.device->configure();
  ASSERT_FALSE(configured);
  EXPECT_EQ(configured.error().message, "motion configure failed");
  EXPECT_EQ(parts.journal,
            (std::vector<std::string>{"io configure", "motion configure", "io deactivate"}));
  EXPECT_EQ(parts.device->state(), LifecycleState::unconfigured);
}

TEST(CompositeDevice, MotionActivateFailureDeactivatesTheIo) {
  Parts parts;
  parts.motion->fail_activate = true;
  ASSERT_TRUE(parts.device->configure());
  ASSERT_FALSE(parts.device->activate());
  EXPECT_EQ(parts.journal.back(), "io deactivate");
  EXPECT_EQ(parts.device->state(), LifecycleState::inactive);
}

TEST(CompositeDevice, IoFailureLeavesTheMotionAlone) {
  Parts parts;
  parts.io->fail_configure = true;
  ASSERT_FALSE(parts.device->configure());
  EXPECT_EQ(parts.journal, (std::vector<std::string>{"io configure"}));
}

TEST(CompositeDevice, InterfacesComeFromTheirPart) {
  Parts parts;
  EXPECT_EQ(parts.device->encoders(), static_cast<EncoderInterface*>(parts.motion));
  EXPECT_EQ(parts.device->digital_inputs(), static_cast<DigitalInputInterface*>(parts.io));
  EXPECT_EQ(parts.device->actuators(), nullptr);
  EXPECT_EQ(parts.device->digital_outputs(), nullptr);
}

}  // namespace
}  // namespace trainer::hal
