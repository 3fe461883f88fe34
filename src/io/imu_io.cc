#include "ltlo/io/imu_io.h"

#include <array>
#include <cctype>
#include <fstream>
#include <string>
#include <vector>

#include "imu_streams.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "parsers.h"
#include "text_parse.h"

namespace ltlo::io {
namespace {

using detail::MergeSummary;
using detail::MergeTimes;
using detail::OrderCounts;
using detail::ReadingStream;
using detail::StampedReading;

enum class TimeUnit { kSeconds, kNanoseconds };

// The marker of a sensor missing from an imu.txt row: "nan" in any case; a sign is accepted
// because C's printf writes a NaN with its sign bit set as "-nan".
bool isNanMarker(const std::string& token) {
  const size_t start = token.size() == 4 && (token[0] == '-' || token[0] == '+') ? 1 : 0;
  if (token.size() - start != 3) return false;
  const auto lower = [&](size_t i) {
    return std::tolower(static_cast<unsigned char>(token[start + i]));
  };
  return lower(0) == 'n' && lower(1) == 'a' && lower(2) == 'n';
}

// Reads fields[first .. first + 2] into values[slot .. slot + 2]. Returns false when all three
// are the nan marker (that sensor is missing from the row, allowed with `allow_missing`); one or
// two nan is an error naming the first.
bool parseTriple(const std::vector<std::string>& fields, size_t first, const char* sensor,
                 bool allow_missing, const std::string& path, int line_number,
                 std::array<double, 6>* values, size_t slot) {
  if (allow_missing) {
    size_t num_nan = 0;
    size_t first_nan = 0;
    for (size_t k = 0; k < 3; ++k) {
      if (isNanMarker(fields[first + k]) && num_nan++ == 0) first_nan = k;
    }
    if (num_nan == 3) return false;
    if (num_nan > 0) {
      throw InputError(
          path, line_number,
          "value " + std::to_string(first + first_nan + 1) + " is not finite: '" +
              fields[first + first_nan] + "' (the " + sensor + " triple '" + fields[first] + " " +
              fields[first + 1] + " " + fields[first + 2] +
              "' is partly nan; a sensor missing from a row is written 'nan nan nan')");
    }
  }
  for (size_t k = 0; k < 3; ++k) {
    (*values)[slot + k] = detail::parseFinite(
        fields[first + k], "value " + std::to_string(first + k + 1), path, line_number);
  }
  return true;
}

// Reads the "t v1 .. vn" lines of an IMU file (separator and/or whitespace) in file order, each
// value checked finite. With `allow_half_rows` (imu.txt, n = 6) either triple may be
// "nan nan nan" (the row's has_gyro / has_acc say which is present), never both.
ReadingStream parseReadings(std::istream& in, const std::string& path, char separator,
                            size_t num_values, TimeUnit unit, bool allow_half_rows) {
  ReadingStream rows;
  detail::LineReader lines(in);
  while (lines.next()) {
    const std::string& line = lines.line();
    const int line_number = lines.number();
    if (detail::isCommentOrBlank(line)) continue;
    // EuRoC headers start with "#", but some exports start with a plain "timestamp" header.
    if (rows.empty() && line.find("timestamp") != std::string::npos) continue;
    const std::vector<std::string> fields = detail::splitFields(line, separator);
    if (fields.size() != num_values + 1) {
      throw InputError(path, line_number,
                       "expected " + std::to_string(num_values + 1) + " values, found " +
                           std::to_string(fields.size()) + " in '" + line + "'");
    }
    StampedReading row;
    row.line = line_number;
    row.t_s = unit == TimeUnit::kNanoseconds
                  ? detail::parseNanosecondsAsSeconds(fields[0], path, line_number)
                  : detail::parseFinite(fields[0], "timestamp", path, line_number);
    if (num_values == 6) {
      row.has_gyro =
          parseTriple(fields, 1, "gyroscope", allow_half_rows, path, line_number, &row.values, 0);
      row.has_acc = parseTriple(fields, 4, "accelerometer", allow_half_rows, path, line_number,
                                &row.values, 3);
      if (!row.has_gyro && !row.has_acc) {
        throw InputError(
            path, line_number,
            "both sensors missing (gyroscope and accelerometer 'nan nan nan') in '" + line + "'");
      }
    } else {
      for (size_t i = 0; i < num_values; ++i) {
        row.values[i] =
            detail::parseFinite(fields[i + 1], "value " + std::to_string(i + 2), path, line_number);
      }
    }
    rows.push_back(row);
  }
  return rows;
}

// Time order, duplicates and gaps of one stream of a file (one warning line when reordered).
void orderAndCheck(ReadingStream* stream, const std::string& path, const SequenceOptions& options) {
  const OrderCounts counts = detail::putInTimeOrder(stream, path, options.max_imu_reorder_s);
  if (counts.any()) log::warn(detail::orderWarning(path, counts, ""));
  detail::checkImuGaps(*stream, path, "", options);
}

// One sensor's readings of a split imu.txt (values 0..2), full rows included.
ReadingStream sensorStream(const ReadingStream& rows, bool gyro) {
  ReadingStream stream;
  for (const StampedReading& row : rows) {
    if (!(gyro ? row.has_gyro : row.has_acc)) continue;
    StampedReading reading;
    reading.t_s = row.t_s;
    reading.line = row.line;
    for (size_t k = 0; k < 3; ++k) reading.values[k] = row.values[gyro ? k : k + 3];
    stream.push_back(reading);
  }
  return stream;
}

std::string countsText(const char* sensor, const OrderCounts& counts) {
  return std::string(sensor) + " " + std::to_string(counts.duplicates()) + " dropped, " +
         std::to_string(counts.out_of_order) + " sorted";
}

// A split imu.txt: each sensor ordered and checked on its own, then merged onto the gyroscope's
// stamps with the accelerometer interpolated (gyroscope samples it does not cover are dropped).
ImuSamples mergeSplitStream(const ReadingStream& rows, const std::string& path,
                            const SequenceOptions& options) {
  ReadingStream gyro = sensorStream(rows, /*gyro=*/true);
  ReadingStream accel = sensorStream(rows, /*gyro=*/false);
  const OrderCounts gyro_counts = detail::putInTimeOrder(&gyro, path, options.max_imu_reorder_s);
  const OrderCounts accel_counts = detail::putInTimeOrder(&accel, path, options.max_imu_reorder_s);
  if (gyro_counts.any() || accel_counts.any()) {
    OrderCounts total = gyro_counts;
    total += accel_counts;
    log::warn(detail::orderWarning(
        path, total,
        countsText("gyroscope", gyro_counts) + "; " + countsText("accelerometer", accel_counts)));
  }
  detail::checkImuGaps(gyro, path, "gyroscope ", options);
  detail::checkImuGaps(accel, path, "accelerometer ", options);
  MergeSummary summary;
  ImuSamples samples =
      detail::mergeImuStreams(gyro, path, accel, path, MergeTimes::kGyro, &summary);
  log::info(path, ": split stream: accelerometer (", accel.size(),
            " samples) interpolated at the gyroscope's ", gyro.size(), " stamps; ",
            summary.num_dropped, " gyroscope samples outside the accelerometer's span [",
            detail::formatTime(summary.begin_s), ", ", detail::formatTime(summary.end_s),
            "] s dropped");
  return samples;
}

// imu.txt and EuRoC rows: full rows as they are (in time order), or a split stream merged.
ImuSamples samplesFromRows(ReadingStream rows, const std::string& path,
                           const SequenceOptions& options) {
  for (const StampedReading& row : rows) {
    if (!row.has_gyro || !row.has_acc) return mergeSplitStream(rows, path, options);
  }
  orderAndCheck(&rows, path, options);
  return detail::toImuSamples(rows);
}

std::ifstream openImuFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(path, 0, "cannot open IMU file");
  return in;
}

}  // namespace

namespace detail {

ImuSamples parseImuText(std::istream& in, const std::string& path, const SequenceOptions& options) {
  return samplesFromRows(
      parseReadings(in, path, ' ', 6, TimeUnit::kSeconds, /*allow_half_rows=*/true), path, options);
}

ImuSamples parseEurocImuCsv(std::istream& in, const std::string& path,
                            const SequenceOptions& options) {
  return samplesFromRows(
      parseReadings(in, path, ',', 6, TimeUnit::kNanoseconds, /*allow_half_rows=*/false), path,
      options);
}

ImuSamples parseOpenLorisImu(std::istream& accel_in, const std::string& accel_path,
                             std::istream& gyro_in, const std::string& gyro_path,
                             const SequenceOptions& options) {
  ReadingStream accel = parseReadings(accel_in, accel_path, ' ', 3, TimeUnit::kSeconds, false);
  orderAndCheck(&accel, accel_path, options);
  ReadingStream gyro = parseReadings(gyro_in, gyro_path, ' ', 3, TimeUnit::kSeconds, false);
  orderAndCheck(&gyro, gyro_path, options);
  MergeSummary summary;
  ImuSamples samples =
      mergeImuStreams(gyro, gyro_path, accel, accel_path, MergeTimes::kUnion, &summary);
  log::info(gyro_path, " + ", accel_path, ": merged at the union of their stamps inside [",
            formatTime(summary.begin_s), ", ", formatTime(summary.end_s), "] s, ", samples.size(),
            " samples (", summary.num_dropped, " stamps outside it dropped)");
  return samples;
}

}  // namespace detail

ImuSamples readImuText(const std::string& path, const SequenceOptions& options) {
  std::ifstream in = openImuFile(path);
  return detail::parseImuText(in, path, options);
}

ImuSamples readEurocImuCsv(const std::string& path, const SequenceOptions& options) {
  std::ifstream in = openImuFile(path);
  return detail::parseEurocImuCsv(in, path, options);
}

ImuSamples readOpenLorisImu(const std::string& accel_path, const std::string& gyro_path,
                            const SequenceOptions& options) {
  std::ifstream accel = openImuFile(accel_path);
  std::ifstream gyro = openImuFile(gyro_path);
  return detail::parseOpenLorisImu(accel, accel_path, gyro, gyro_path, options);
}

}  // namespace ltlo::io
