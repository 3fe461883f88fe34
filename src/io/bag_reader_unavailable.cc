// ltlo_io built without rosbag_storage (LTLO_WITH_ROSBAG off or not found): every bag entry point
// refuses with an InputError that says how to build with it.
#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/io/sequence_reader.h"

namespace ltlo::io {
namespace {

[[noreturn]] void refuse(const std::string& what) {
  throw InputError(what, 0, "this build reads no ROS bags (rosbag_storage was not found at configure time: "
                            "run scripts/setup.sh and reconfigure)");
}

}  // namespace

SequenceReader SequenceReader::openBag(const std::string& bag_path, const BagTopics&, const SequenceReaderOptions&) {
  refuse(bag_path);
}

void SequenceReader::loadBagImages(int, bool, RgbdImuFrame*) const {
  LTLO_ASSERT(false, "no bag reader in this build, yet a reader has a bag");
}

BagTopics bagTopicPreset(const std::string& name) { refuse("--bag-preset " + name); }
std::string bagTopicPresetNames() { return "tum, realsense, realsense-unite, openloris"; }
std::vector<BagTopicInfo> listBagTopics(const std::string& bag_path) { refuse(bag_path); }
std::string formatBagTopics(const std::vector<BagTopicInfo>&) { return ""; }
bool bagSupportCompiled() { return false; }

}  // namespace ltlo::io
