#pragma once
/// The live viewer's HTTP output (issue 30): an MJPEG stream of the rendered views, the latest
/// frame, the online pose stream as server-sent events and a small status page, served by
/// cpp-httplib (Debian's libcpp-httplib-dev; only this library's .cc sees httplib.h).
///
///   http::MjpegServer server({"127.0.0.1", 8080});   // logs "viewer: http://127.0.0.1:8080/"
///   server.publishJpeg(jpeg_bytes);                   // from the viewer thread
///   server.publishPose(R"({"t_s":1.5,"p":[0,0,1]})");  // from tracking, one JSON line
///
/// Threads: the server owns a listening thread and a pool of ServerOptions::max_clients +
/// kSpareWorkers connection threads (OS names "ltlo.http"), all joined by stop(). Each streaming
/// client holds one pool thread for as long as it watches.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace ltlo::http {

/// Connection threads beyond max_clients, so /, /frame.jpg and /status still answer while every
/// streaming slot is taken.
constexpr int kSpareWorkers = 2;
/// Pose lines kept for /poses clients that fall behind; a client further behind skips the oldest.
constexpr int kPoseBacklog = 1024;

struct ServerOptions {
  std::string bind_address = "127.0.0.1";  ///< "0.0.0.0" opens it to the network (--viewer-bind)
  int port = 0;                            ///< TCP port, [0, 65535]; 0: the OS picks a free one
  /// Streaming clients (/stream.mjpg and /poses together) served at once, [1, 256]; one more gets
  /// 503. The connection pool has max_clients + kSpareWorkers threads.
  int max_clients = 8;
  /// Read, write and keep-alive timeout of a connection in seconds, [1, 60]. A client that takes
  /// no bytes for this long is dropped; it bounds how long stop() waits for a stalled client.
  int io_timeout_s = 1;
};

/// Serves, while it lives:
///   GET /            a small HTML page showing /stream.mjpg and the latest pose from /poses
///   GET /stream.mjpg multipart/x-mixed-replace MJPEG: every published JPEG once per client, the
///                    newest one when a client is behind (a slow client skips frames, it never
///                    queues them); a new client starts with the latest frame
///   GET /frame.jpg   the latest JPEG, 503 before the first
///   GET /poses       text/event-stream: each published pose line as an SSE "data:" event, in
///                    order; a new client starts with the latest line
///   GET /status      JSON: {"frames_published":N,"poses_published":N,"clients":N,"frames_sent":N}
/// Thread-safe: publish* may be called from any thread and never block on a client (they take a
/// short private mutex, never held during network I/O).
class MjpegServer {
 public:
  /// Binds and starts listening (no SO_REUSEPORT: a port in use is an error, not a shared port).
  /// Throws ltlo::ConfigError for options out of range or when it cannot bind, naming
  /// address:port and the reason ("http: cannot listen on 127.0.0.1:8080: Address already in use").
  explicit MjpegServer(const ServerOptions& options);
  ~MjpegServer();  ///< stop()
  MjpegServer(const MjpegServer&) = delete;
  MjpegServer& operator=(const MjpegServer&) = delete;

  /// Idempotent and thread-safe: wakes every streaming client, stops the server and joins its
  /// threads. Returns within about io_timeout_s even with a stalled client connected.
  void stop();
  int port() const;  ///< the bound port

  /// Publishes one JPEG (the bytes of a .jpg file) as the latest frame.
  void publishJpeg(std::vector<unsigned char> jpeg);
  /// Publishes one pose line: one line of JSON, no newline (LTLO_ASSERT).
  void publishPose(std::string json_line);

  std::uint64_t framesPublished() const;
  std::uint64_t posesPublished() const;
  int streamingClients() const;      ///< clients currently on /stream.mjpg or /poses
  std::uint64_t framesSent() const;  ///< JPEG parts written in full to all stream clients

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ltlo::http
