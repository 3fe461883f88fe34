#include <istream>

#include "ltlo/core/errors.h"
#include "parsers.h"
#include "text_parse.h"

namespace ltlo::io::detail {
namespace {

void checkFrameTimeIncreases(double t_s, double previous_s, bool has_previous,
                             const std::string& list_path, int line) {
  if (has_previous && t_s <= previous_s) {
    throw InputError(
        list_path, line,
        "timestamp " + formatTime(t_s) + " is not after the previous " + formatTime(previous_s));
  }
}

}  // namespace

std::vector<ListedImage> parseImageList(std::istream& in, const std::string& dir,
                                        const std::string& list_path) {
  std::vector<ListedImage> images;
  LineReader lines(in);
  while (lines.next()) {
    const std::string& line = lines.line();
    const int line_number = lines.number();
    if (isCommentOrBlank(line)) continue;
    const std::vector<std::string> fields = splitFields(line);
    if (fields.size() != 2) {
      throw InputError(list_path, line_number, "expected 'timestamp path', found '" + line + "'");
    }
    ListedImage image;
    image.t_s = parseFinite(fields[0], "timestamp", list_path, line_number);
    image.path = joinPath(dir, fields[1]);
    image.line = line_number;
    checkFrameTimeIncreases(image.t_s, images.empty() ? 0.0 : images.back().t_s, !images.empty(),
                            list_path, line_number);
    images.push_back(image);
  }
  return images;
}

std::vector<FrameFiles> parseAssociations(std::istream& in, const std::string& dir,
                                          const std::string& list_path) {
  std::vector<FrameFiles> frames;
  LineReader lines(in);
  while (lines.next()) {
    const std::string& line = lines.line();
    const int line_number = lines.number();
    if (isCommentOrBlank(line)) continue;
    const std::vector<std::string> fields = splitFields(line);
    if (fields.size() != 4) {
      throw InputError(list_path, line_number,
                       "expected 't_rgb rgb_path t_depth depth_path', found '" + line + "'");
    }
    FrameFiles frame;
    frame.t_s = parseFinite(fields[0], "colour timestamp", list_path, line_number);
    frame.color_path = joinPath(dir, fields[1]);
    frame.depth_t_s = parseFinite(fields[2], "depth timestamp", list_path, line_number);
    frame.depth_path = joinPath(dir, fields[3]);
    frame.color_list_path = frame.depth_list_path = list_path;
    frame.color_list_line = frame.depth_list_line = line_number;
    checkFrameTimeIncreases(frame.t_s, frames.empty() ? 0.0 : frames.back().t_s, !frames.empty(),
                            list_path, line_number);
    frames.push_back(frame);
  }
  return frames;
}

}  // namespace ltlo::io::detail
