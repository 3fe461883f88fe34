#include "ltlo/http/mjpeg_server.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "common/log_capture.h"
#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/thread_names.h"

namespace ltlo::http {
namespace {

using Jpeg = std::vector<unsigned char>;

constexpr int kSocketTimeout_s = 10;  // a client read or write that waits longer fails the test

/// Polls one of the server's counters until `done` holds, for at most 10 s (server counters
/// have no event to wait on; the short waits are between checks of a counter, not a guess of
/// how long something takes).
bool waitUntil(const std::function<bool()>& done) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

Jpeg encodeJpeg(const cv::Mat& image, int quality = 90) {
  Jpeg jpeg;
  cv::imencode(".jpg", image, jpeg, {cv::IMWRITE_JPEG_QUALITY, quality});
  return jpeg;
}

/// A colour gradient with `index` in it, so successive frames differ.
Jpeg gradientJpeg(int width, int height, int index) {
  cv::Mat image(height, width, CV_8UC3);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      image.at<cv::Vec3b>(v, u) =
          cv::Vec3b(static_cast<uint8_t>(u + index), static_cast<uint8_t>(v),
                    static_cast<uint8_t>(index * 7));
    }
  }
  return encodeJpeg(image);
}

/// Uniform noise: a JPEG that barely compresses (about 0.5 MB at 640 x 480).
Jpeg noiseJpeg(int width, int height, std::uint32_t seed) {
  cv::Mat image(height, width, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return encodeJpeg(image, 95);
}

cv::Size decodedSize(const std::string& bytes) {
  const cv::Mat buffer(1, static_cast<int>(bytes.size()), CV_8UC1, const_cast<char*>(bytes.data()));
  const cv::Mat image = cv::imdecode(buffer, cv::IMREAD_COLOR);
  return image.empty() ? cv::Size() : image.size();
}

std::string asString(const Jpeg& jpeg) { return std::string(jpeg.begin(), jpeg.end()); }

/// A raw HTTP/1.1 client over a loopback TCP socket: sends one GET and reads the response
/// incrementally, so a test sees the wire format and can stop reading (stall) at will.
class RawClient {
 public:
  /// receive_buffer_bytes > 0 shrinks the socket's receive buffer (a stalled client then fills
  /// up quickly).
  RawClient(int port, const std::string& path, int receive_buffer_bytes = 0) {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    if (receive_buffer_bytes > 0) {
      setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes, sizeof(receive_buffer_bytes));
    }
    timeval timeout{kSocketTimeout_s, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
    setsockopt(fd_, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof(timeout));
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof(address)) == 0;
    const std::string request =
        "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
    connected_ = connected_ && send(fd_, request.data(), request.size(), MSG_NOSIGNAL) ==
                                   static_cast<ssize_t>(request.size());
  }
  RawClient(const RawClient&) = delete;
  RawClient& operator=(const RawClient&) = delete;
  ~RawClient() { close(); }

  bool connected() const { return connected_; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  /// Reads the status line and headers; returns the status code (0 on failure). The headers are
  /// kept in headers().
  int readHead() {
    std::size_t end = std::string::npos;
    while ((end = buffer_.find("\r\n\r\n")) == std::string::npos) {
      if (!receive()) return 0;
    }
    headers_ = buffer_.substr(0, end + 2);
    buffer_.erase(0, end + 4);
    int status = 0;
    return std::sscanf(headers_.c_str(), "HTTP/1.1 %d", &status) == 1 ? status : 0;
  }
  const std::string& headers() const { return headers_; }

  /// The rest of the body, up to the server closing the connection.
  std::string readToEnd() {
    while (receive()) {
    }
    return std::exchange(buffer_, std::string());
  }

  /// The next part of a multipart/x-mixed-replace body (after readHead()); nullopt on EOF,
  /// timeout or a malformed part.
  std::optional<std::string> readPart() {
    const std::string delimiter = "--ltloframe\r\n";
    std::size_t header_end = std::string::npos;
    while ((header_end = buffer_.find("\r\n\r\n")) == std::string::npos) {
      if (!receive()) return std::nullopt;
    }
    if (buffer_.compare(0, delimiter.size(), delimiter) != 0) return std::nullopt;
    const std::string part_headers = buffer_.substr(0, header_end);
    const std::size_t length_at = part_headers.find("Content-Length: ");
    if (length_at == std::string::npos ||
        part_headers.find("Content-Type: image/jpeg") == std::string::npos) {
      return std::nullopt;
    }
    const std::size_t length = std::stoul(part_headers.substr(length_at + 16));
    const std::size_t body_at = header_end + 4;
    while (buffer_.size() < body_at + length + 2) {
      if (!receive()) return std::nullopt;
    }
    if (buffer_.compare(body_at + length, 2, "\r\n") != 0) return std::nullopt;
    std::string part = buffer_.substr(body_at, length);
    buffer_.erase(0, body_at + length + 2);
    return part;
  }

  /// The data of the next server-sent event (after readHead()); nullopt on EOF or timeout.
  std::optional<std::string> readEvent() {
    std::size_t end = std::string::npos;
    while ((end = buffer_.find("\n\n")) == std::string::npos) {
      if (!receive()) return std::nullopt;
    }
    std::string event = buffer_.substr(0, end);
    buffer_.erase(0, end + 2);
    if (event.compare(0, 6, "data: ") != 0) return std::nullopt;
    return event.substr(6);
  }

 private:
  bool receive() {
    char chunk[65536];
    const ssize_t n = fd_ < 0 ? -1 : recv(fd_, chunk, sizeof(chunk), 0);
    if (n <= 0) return false;
    buffer_.append(chunk, static_cast<std::size_t>(n));
    return true;
  }

  int fd_ = -1;
  bool connected_ = false;
  std::string buffer_;  // received, not yet consumed
  std::string headers_;
};

ServerOptions loopback() { return ServerOptions{}; }  // 127.0.0.1, a free port

int countHttpThreads() {
  const std::vector<std::string> names = runningNamedThreads();
  return static_cast<int>(std::count(names.begin(), names.end(), "ltlo.http"));
}

TEST(MjpegServer, FrameJpgServesThePublishedBytes) {
  test::LogCapture capture;
  MjpegServer server(loopback());
  ASSERT_GT(server.port(), 0);
  EXPECT_TRUE(capture.contains("viewer: http://127.0.0.1:" + std::to_string(server.port()) + "/"));
  {
    RawClient before(server.port(), "/frame.jpg");
    EXPECT_EQ(before.readHead(), 503);  // nothing published yet
  }
  const Jpeg jpeg = gradientJpeg(320, 240, 3);
  server.publishJpeg(jpeg);
  RawClient client(server.port(), "/frame.jpg");
  ASSERT_EQ(client.readHead(), 200);
  EXPECT_NE(client.headers().find("Content-Type: image/jpeg"), std::string::npos);
  const std::string body = client.readToEnd();
  EXPECT_EQ(body, asString(jpeg));
  EXPECT_EQ(decodedSize(body), cv::Size(320, 240));
  EXPECT_EQ(server.framesPublished(), 1u);
}

TEST(MjpegServer, StreamDeliversEveryFrameToAReader) {
  MjpegServer server(loopback());
  RawClient client(server.port(), "/stream.mjpg");
  ASSERT_EQ(client.readHead(), 200);
  EXPECT_NE(client.headers().find("multipart/x-mixed-replace; boundary=ltloframe"),
            std::string::npos);
  ASSERT_EQ(server.streamingClients(), 1);
  constexpr int kFrames = 20;
  for (int i = 0; i < kFrames; ++i) {
    const Jpeg jpeg = gradientJpeg(160 + 8 * i, 120, i);  // each frame its own size
    server.publishJpeg(jpeg);
    const std::optional<std::string> part = client.readPart();
    ASSERT_TRUE(part.has_value()) << "part " << i;
    EXPECT_EQ(*part, asString(jpeg)) << "part " << i;
    EXPECT_EQ(decodedSize(*part), cv::Size(160 + 8 * i, 120)) << "part " << i;
  }
  // The server counts a part after its last byte is written, so the reader may hold part 20 before
  // the count does (seen once on a loaded machine: 19). The same server thread counts part 20
  // before it writes part 21: once part 21 is read, 20 or 21 parts are counted.
  const Jpeg last = gradientJpeg(64, 48, kFrames);
  server.publishJpeg(last);
  const std::optional<std::string> part = client.readPart();
  ASSERT_TRUE(part.has_value());
  EXPECT_EQ(*part, asString(last));
  EXPECT_GE(server.framesSent(), static_cast<std::uint64_t>(kFrames));
  EXPECT_LE(server.framesSent(), static_cast<std::uint64_t>(kFrames + 1));
}

TEST(MjpegServer, NewClientStartsWithTheLatestFrame) {
  MjpegServer server(loopback());
  const Jpeg first = gradientJpeg(64, 48, 1);
  const Jpeg latest = gradientJpeg(64, 48, 2);
  server.publishJpeg(first);
  server.publishJpeg(latest);
  RawClient client(server.port(), "/stream.mjpg");
  ASSERT_EQ(client.readHead(), 200);
  const std::optional<std::string> part = client.readPart();
  ASSERT_TRUE(part.has_value());
  EXPECT_EQ(*part, asString(latest));
}

TEST(MjpegServer, SlowClientSkipsToTheNewestFrame) {
  // A slow client, not a stalled one: the server's write timeout as long as the client's, so a loaded
  // machine (a sanitizer build beside other jobs) that drains the socket late does not drop it.
  ServerOptions options = loopback();
  options.io_timeout_s = kSocketTimeout_s;
  MjpegServer server(options);
  RawClient client(server.port(), "/stream.mjpg", /*receive_buffer_bytes=*/4096);
  ASSERT_EQ(client.readHead(), 200);
  ASSERT_EQ(server.streamingClients(), 1);
  constexpr int kFrames = 50;
  std::vector<Jpeg> jpegs;
  for (int i = 0; i < kFrames; ++i) jpegs.push_back(noiseJpeg(640, 480, 100 + i));
  for (const Jpeg& jpeg : jpegs) server.publishJpeg(jpeg);  // the client is not reading yet
  const std::string newest = asString(jpegs.back());
  // The server finishes the part it was writing, then sends only the newest: read until the
  // newest arrives; far fewer parts than frames published reached the client.
  int parts = 0;
  std::optional<std::string> part;
  do {
    part = client.readPart();
    ASSERT_TRUE(part.has_value()) << "after " << parts << " parts";
    ++parts;
  } while (*part != newest);
  EXPECT_LT(parts, kFrames / 2);
  // Counted after its last byte is written: the reader may have the newest before the count does.
  EXPECT_TRUE(waitUntil([&] { return server.framesSent() == static_cast<std::uint64_t>(parts); }))
      << server.framesSent() << " parts counted, " << parts << " read";
  EXPECT_EQ(server.framesPublished(), static_cast<std::uint64_t>(kFrames));
}

TEST(MjpegServer, StalledClientBlocksNeitherPublishNorOtherClients) {
  MjpegServer server(loopback());
  // Sends its request and never reads: its buffers fill and the server's writes to it stall.
  RawClient stalled(server.port(), "/stream.mjpg", /*receive_buffer_bytes=*/4096);
  ASSERT_TRUE(stalled.connected());
  ASSERT_TRUE(waitUntil([&] { return server.streamingClients() == 1; }));
  RawClient reader(server.port(), "/stream.mjpg");
  ASSERT_EQ(reader.readHead(), 200);
  ASSERT_TRUE(waitUntil([&] { return server.streamingClients() == 2; }));

  std::vector<Jpeg> jpegs;
  for (int i = 0; i < 4; ++i) jpegs.push_back(noiseJpeg(640, 480, 7 + i));
  constexpr int kFrames = 200;
  int received = 0;
  for (int i = 0; i < kFrames; ++i) {
    server.publishJpeg(jpegs[i % 4]);  // returns at once: would hang the test otherwise
    const std::optional<std::string> part = reader.readPart();
    ASSERT_TRUE(part.has_value()) << "frame " << i;
    EXPECT_EQ(*part, asString(jpegs[i % 4])) << "frame " << i;
    if (i % 50 == 0) {
      EXPECT_EQ(decodedSize(*part), cv::Size(640, 480)) << "frame " << i;
    }
    ++received;
  }
  EXPECT_EQ(received, kFrames);
  EXPECT_EQ(server.framesPublished(), static_cast<std::uint64_t>(kFrames));
  // The stalled client took only what its socket buffers hold (about 4 MB, a few frames).
  EXPECT_LT(server.framesSent(), static_cast<std::uint64_t>(2 * kFrames));

  const auto stop_start = std::chrono::steady_clock::now();
  server.stop();  // the stalled client is still connected
  const double stop_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - stop_start).count();
  RecordProperty("stop_ms", static_cast<int>(stop_s * 1000.0));
  EXPECT_EQ(countHttpThreads(), 0);
  EXPECT_FALSE(reader.readPart().has_value());  // the stream ended with the server
}

TEST(MjpegServer, PosesArriveAsServerSentEventsInOrder) {
  MjpegServer server(loopback());
  RawClient client(server.port(), "/poses");
  ASSERT_EQ(client.readHead(), 200);
  EXPECT_NE(client.headers().find("Content-Type: text/event-stream"), std::string::npos);
  ASSERT_EQ(server.streamingClients(), 1);
  constexpr int kPoses = 50;
  std::vector<std::string> lines;
  for (int i = 0; i < kPoses; ++i) {
    lines.push_back("{\"t_s\":" + std::to_string(0.1 * i) + ",\"frame\":" + std::to_string(i) +
                    "}");
    server.publishPose(lines.back());  // all published before reading: none may be lost
  }
  for (int i = 0; i < kPoses; ++i) {
    const std::optional<std::string> event = client.readEvent();
    ASSERT_TRUE(event.has_value()) << "event " << i;
    EXPECT_EQ(*event, lines[i]);
  }
  EXPECT_EQ(server.posesPublished(), static_cast<std::uint64_t>(kPoses));
}

TEST(MjpegServer, PublishersOnOtherThreadsReachReadingClients) {
  MjpegServer server(loopback());
  RawClient video(server.port(), "/stream.mjpg");
  RawClient poses(server.port(), "/poses");
  ASSERT_EQ(video.readHead(), 200);
  ASSERT_EQ(poses.readHead(), 200);
  ASSERT_EQ(server.streamingClients(), 2);
  constexpr int kCount = 100;
  std::vector<Jpeg> jpegs;
  for (int i = 0; i < kCount; ++i) jpegs.push_back(gradientJpeg(64, 48, i));
  // Frames from one thread, poses from another, as the viewer and tracking threads would.
  std::thread frame_publisher([&] {
    for (const Jpeg& jpeg : jpegs) server.publishJpeg(jpeg);
  });
  std::thread pose_publisher([&] {
    for (int i = 0; i < kCount; ++i) server.publishPose("{\"frame\":" + std::to_string(i) + "}");
  });
  // The video client may skip frames but ends on the last one; the pose client gets every line.
  const std::string last_frame = asString(jpegs.back());
  std::optional<std::string> part;
  do {
    part = video.readPart();
    ASSERT_TRUE(part.has_value());
    EXPECT_EQ(decodedSize(*part), cv::Size(64, 48));
  } while (*part != last_frame);
  for (int i = 0; i < kCount; ++i) {
    const std::optional<std::string> event = poses.readEvent();
    ASSERT_TRUE(event.has_value()) << "event " << i;
    EXPECT_EQ(*event, "{\"frame\":" + std::to_string(i) + "}");
  }
  frame_publisher.join();
  pose_publisher.join();
  EXPECT_EQ(server.framesPublished(), static_cast<std::uint64_t>(kCount));
  EXPECT_EQ(server.posesPublished(), static_cast<std::uint64_t>(kCount));
}

TEST(MjpegServer, PoseWithANewlineIsRejected) {
  MjpegServer server(loopback());
  EXPECT_THROW(server.publishPose("{\"a\":1}\n{\"b\":2}"), AssertionError);
  EXPECT_EQ(server.posesPublished(), 0u);
}

TEST(MjpegServer, PortInUseThrowsNamingThePort) {
  MjpegServer first(loopback());
  ServerOptions same = loopback();
  same.port = first.port();
  try {
    MjpegServer second(same);
    FAIL() << "a second server bound port " << same.port;
  } catch (const ConfigError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("127.0.0.1:" + std::to_string(same.port)), std::string::npos) << message;
    EXPECT_NE(message.find("in use"), std::string::npos) << message;
  }
  // The first server still serves.
  RawClient client(first.port(), "/status");
  EXPECT_EQ(client.readHead(), 200);
}

TEST(MjpegServer, OptionsOutOfRangeThrowNamingTheField) {
  ServerOptions options = loopback();
  options.max_clients = 0;
  try {
    MjpegServer server(options);
    FAIL() << "max_clients = 0 accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("max_clients = 0"), std::string::npos) << e.what();
  }
  options = loopback();
  options.port = 70000;
  EXPECT_THROW(MjpegServer server(options), ConfigError);
}

TEST(MjpegServer, StreamingClientsReturnsToZeroAfterDisconnects) {
  MjpegServer server(loopback());
  server.publishJpeg(gradientJpeg(64, 48, 0));
  {
    RawClient video(server.port(), "/stream.mjpg");
    RawClient poses(server.port(), "/poses");
    ASSERT_EQ(video.readHead(), 200);
    ASSERT_EQ(poses.readHead(), 200);
    ASSERT_TRUE(video.readPart().has_value());
    EXPECT_EQ(server.streamingClients(), 2);
  }  // both close while nothing new is published: the idle handlers notice on their probe
  EXPECT_TRUE(waitUntil([&] { return server.streamingClients() == 0; }))
      << server.streamingClients() << " clients";
}

TEST(MjpegServer, ClientsBeyondMaxClientsGet503AndStatusStillAnswers) {
  ServerOptions options = loopback();
  options.max_clients = 1;
  MjpegServer server(options);
  EXPECT_TRUE(
      waitUntil([&] { return countHttpThreads() == 1 + options.max_clients + kSpareWorkers; }));
  RawClient first(server.port(), "/poses");
  ASSERT_EQ(first.readHead(), 200);
  RawClient second(server.port(), "/stream.mjpg");
  EXPECT_EQ(second.readHead(), 503);
  server.publishJpeg(gradientJpeg(64, 48, 0));
  RawClient status(server.port(), "/status");
  ASSERT_EQ(status.readHead(), 200);
  EXPECT_NE(status.headers().find("application/json"), std::string::npos);
  EXPECT_EQ(status.readToEnd(),
            "{\"frames_published\":1,\"poses_published\":0,\"clients\":1,\"frames_sent\":0}\n");
}

TEST(MjpegServer, IndexPageShowsTheStreamAndThePoses) {
  MjpegServer server(loopback());
  RawClient client(server.port(), "/");
  ASSERT_EQ(client.readHead(), 200);
  EXPECT_NE(client.headers().find("text/html"), std::string::npos);
  const std::string page = client.readToEnd();
  EXPECT_NE(page.find("<img src=\"/stream.mjpg\""), std::string::npos);
  EXPECT_NE(page.find("EventSource('/poses')"), std::string::npos);
}

TEST(MjpegServer, StopIsIdempotentAndJoinsEveryThread) {
  const int before = countHttpThreads();
  ASSERT_EQ(before, 0);
  MjpegServer server(loopback());
  EXPECT_TRUE(waitUntil(  // the pool threads name themselves as they start
      [&] { return countHttpThreads() == 1 + ServerOptions{}.max_clients + kSpareWorkers; }));
  RawClient idle(server.port(), "/stream.mjpg");  // a streaming client waiting for a frame
  ASSERT_EQ(idle.readHead(), 200);
  server.stop();
  EXPECT_EQ(countHttpThreads(), 0);
  server.stop();
  EXPECT_FALSE(idle.readPart().has_value());    // its stream ended
  server.publishJpeg(gradientJpeg(64, 48, 0));  // publishing after stop is harmless
  EXPECT_EQ(server.framesPublished(), 1u);
}

}  // namespace
}  // namespace ltlo::http
