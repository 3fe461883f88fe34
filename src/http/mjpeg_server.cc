#include "ltlo/http/mjpeg_server.h"

#include <httplib.h>
#include <pthread.h>
#include <signal.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

#include "ltlo/core/assert.h"
#include "ltlo/core/errors.h"
#include "ltlo/core/log.h"
#include "worker_pool.h"

namespace ltlo::http {
namespace {

using Jpeg = std::vector<unsigned char>;

constexpr char kBoundary[] = "ltloframe";
/// How often an idle streaming handler checks that its client is still there (a closed
/// connection is only noticed on a write or a probe, and no write happens while nothing is new).
constexpr std::chrono::milliseconds kProbeInterval(200);

constexpr char kIndexHtml[] = R"html(<!DOCTYPE html>
<html>
<head>
<meta charset="utf-8">
<title>LTLO-SLAM live view</title>
<style>
body { background: #111; color: #ddd; font-family: monospace; margin: 0; padding: 8px; }
img { max-width: 100%; display: block; }
</style>
</head>
<body>
<img src="/stream.mjpg" alt="live view">
<pre id="pose">waiting for the first pose ...</pre>
<script>
const pose = document.getElementById('pose');
const events = new EventSource('/poses');
events.onmessage = (event) => { pose.textContent = event.data; };
events.onerror = () => { pose.textContent = 'pose stream disconnected, retrying ...'; };
</script>
</body>
</html>
)html";

/// "host:port", with brackets around an IPv6 literal.
std::string hostPort(const std::string& address, int port) {
  const bool ipv6 = address.find(':') != std::string::npos;
  return (ipv6 ? "[" + address + "]" : address) + ":" + std::to_string(port);
}

void checkRange(const char* name, int value, int lo, int hi) {
  if (value < lo || value > hi) {
    throw ConfigError("http: ServerOptions." + std::string(name) + " = " + std::to_string(value) +
                      ", expected an integer in [" + std::to_string(lo) + ", " +
                      std::to_string(hi) + "]");
  }
}

/// Where one streaming client is: the last frame generation or pose index it was sent.
struct StreamCursor {
  std::uint64_t sent_generation = 0;  ///< frames: generation of the last part written
  std::uint64_t next_pose = 0;        ///< poses: index of the next line to send
};

}  // namespace

struct MjpegServer::Impl {
  ServerOptions options;
  httplib::Server server;
  std::thread listener;
  int port = 0;

  std::mutex stop_mutex;  // serialises stop(); taken before mutex, never inside it

  mutable std::mutex mutex;         // guards the fields below up to `changed`; never held for I/O
  std::condition_variable changed;  // a frame, a pose, stop, the listener's start or end
  bool stopping = false;
  bool listening = false;      // the listener built its pool: server.stop() now takes effect
  bool listener_done = false;  // listen_after_bind() returned
  std::uint64_t frame_generation = 0;  // frames published so far; the latest has this number
  std::shared_ptr<const Jpeg> latest_jpeg;
  std::uint64_t poses_published = 0;
  std::deque<std::string> recent_poses;  // the last <= kPoseBacklog lines, oldest first
  int streaming_clients = 0;

  std::atomic<std::uint64_t> frames_sent{0};

  /// Waits under `lock` until has_news() or stop; while idle, probes every kProbeInterval that
  /// the client is still connected (without the lock: the probe may wait for the socket). False
  /// when the stream should end (stopping or client gone).
  template <typename HasNews>
  bool waitForNews(std::unique_lock<std::mutex>& lock, httplib::DataSink& sink, HasNews has_news) {
    while (!stopping && !has_news()) {
      if (changed.wait_for(lock, kProbeInterval) == std::cv_status::timeout && !stopping &&
          !has_news()) {
        lock.unlock();
        const bool connected = sink.is_writable();
        lock.lock();
        if (!connected) return false;
      }
    }
    return !stopping;
  }

  /// One content-provider call of /stream.mjpg: waits for a newer frame, writes it as one part.
  bool sendNextFrame(StreamCursor& cursor, httplib::DataSink& sink) {
    std::shared_ptr<const Jpeg> jpeg;
    {
      std::unique_lock<std::mutex> lock(mutex);
      if (!waitForNews(lock, sink, [&] { return frame_generation > cursor.sent_generation; })) {
        return false;
      }
      jpeg = latest_jpeg;  // the newest: frames in between are skipped, never queued
      cursor.sent_generation = frame_generation;
    }
    const std::string header =
        std::string("--") + kBoundary +
        "\r\nContent-Type: image/jpeg\r\nContent-Length: " + std::to_string(jpeg->size()) +
        "\r\n\r\n";
    const char* data = reinterpret_cast<const char*>(jpeg->data());
    if (!sink.write(header.data(), header.size()) || !sink.write(data, jpeg->size()) ||
        !sink.write("\r\n", 2)) {
      return false;  // client gone or stalled past the write timeout: drop it
    }
    frames_sent.fetch_add(1, std::memory_order_relaxed);
    return true;
  }

  /// One content-provider call of /poses: waits for new lines, writes them as SSE events.
  bool sendNewPoses(StreamCursor& cursor, httplib::DataSink& sink) {
    std::string events;
    {
      std::unique_lock<std::mutex> lock(mutex);
      if (!waitForNews(lock, sink, [&] { return poses_published > cursor.next_pose; })) {
        return false;
      }
      const std::uint64_t oldest = poses_published - recent_poses.size();
      for (std::uint64_t i = std::max(cursor.next_pose, oldest); i < poses_published; ++i) {
        events += "data: " + recent_poses[i - oldest] + "\n\n";
      }
      cursor.next_pose = poses_published;
    }
    return sink.write(events.data(), events.size());
  }

  /// Takes a streaming slot, or answers 503 when all max_clients are taken. Starts the cursor at
  /// the latest frame and pose, so a new client sees the current state at once.
  std::shared_ptr<StreamCursor> openStream(httplib::Response& res) {
    std::lock_guard<std::mutex> lock(mutex);
    if (streaming_clients >= options.max_clients) {
      res.status = 503;
      res.set_content("too many streaming clients (max_clients = " +
                          std::to_string(options.max_clients) + ")\n",
                      "text/plain");
      return nullptr;
    }
    ++streaming_clients;
    auto cursor = std::make_shared<StreamCursor>();
    cursor->sent_generation = frame_generation > 0 ? frame_generation - 1 : 0;
    cursor->next_pose = poses_published > 0 ? poses_published - 1 : 0;
    return cursor;
  }

  void closeStream() {
    std::lock_guard<std::mutex> lock(mutex);
    --streaming_clients;
  }

  void addRoutes() {
    server.Get("/", [](const httplib::Request&, httplib::Response& res) {
      res.set_content(kIndexHtml, "text/html; charset=utf-8");
    });
    server.Get("/frame.jpg", [this](const httplib::Request&, httplib::Response& res) {
      std::shared_ptr<const Jpeg> jpeg;
      {
        std::lock_guard<std::mutex> lock(mutex);
        jpeg = latest_jpeg;
      }
      res.set_header("Cache-Control", "no-cache");
      if (!jpeg) {
        res.status = 503;
        res.set_content("no frame published yet\n", "text/plain");
        return;
      }
      res.set_content(reinterpret_cast<const char*>(jpeg->data()), jpeg->size(), "image/jpeg");
    });
    server.Get("/status", [this](const httplib::Request&, httplib::Response& res) {
      std::string json;
      {
        std::lock_guard<std::mutex> lock(mutex);
        json = "{\"frames_published\":" + std::to_string(frame_generation) +
               ",\"poses_published\":" + std::to_string(poses_published) +
               ",\"clients\":" + std::to_string(streaming_clients) +
               ",\"frames_sent\":" + std::to_string(frames_sent.load()) + "}\n";
      }
      res.set_header("Cache-Control", "no-cache");
      res.set_content(json, "application/json");
    });
    // The streams have no length: the body ends when the connection closes. Not chunked, so
    // httplib never compresses them.
    server.Get("/stream.mjpg", [this](const httplib::Request&, httplib::Response& res) {
      std::shared_ptr<StreamCursor> cursor = openStream(res);
      if (!cursor) return;
      res.set_header("Cache-Control", "no-cache");
      res.set_content_provider(
          std::string("multipart/x-mixed-replace; boundary=") + kBoundary,
          [this, cursor](std::size_t, httplib::DataSink& sink) {
            return sendNextFrame(*cursor, sink);
          },
          [this](bool) { closeStream(); });
    });
    server.Get("/poses", [this](const httplib::Request&, httplib::Response& res) {
      std::shared_ptr<StreamCursor> cursor = openStream(res);
      if (!cursor) return;
      res.set_header("Cache-Control", "no-cache");
      res.set_content_provider(
          "text/event-stream",
          [this, cursor](std::size_t, httplib::DataSink& sink) {
            return sendNewPoses(*cursor, sink);
          },
          [this](bool) { closeStream(); });
    });
  }

  /// The listening thread: accepts until server.stop().
  void listen() {
    log::setThreadName("http");
    // A write to a client that just closed raises SIGPIPE in the writing thread; blocked here, the
    // pool threads (created by this one) inherit the mask and see EPIPE instead, and the process'
    // signal handling stays untouched.
    sigset_t pipe_signal;
    sigemptyset(&pipe_signal);
    sigaddset(&pipe_signal, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_signal, nullptr);
    const bool clean = server.listen_after_bind();
    bool was_stopping = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      listener_done = true;
      was_stopping = stopping;
    }
    changed.notify_all();
    if (!clean && !was_stopping) {
      log::error("http: the server on ", hostPort(options.bind_address, port),
                 " stopped accepting connections");
    }
  }
};

MjpegServer::MjpegServer(const ServerOptions& options) : impl_(std::make_unique<Impl>()) {
  checkRange("port", options.port, 0, 65535);
  checkRange("max_clients", options.max_clients, 1, 256);
  checkRange("io_timeout_s", options.io_timeout_s, 1, 60);
  Impl& impl = *impl_;
  impl.options = options;
  httplib::Server& server = impl.server;
  // httplib's default sets SO_REUSEPORT as well, which lets a second server share a port in use
  // (connections split between them). SO_REUSEADDR alone only allows a restart over TIME_WAIT.
  server.set_socket_options([](socket_t sock) {
    const int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  server.set_read_timeout(options.io_timeout_s, 0);
  server.set_write_timeout(options.io_timeout_s, 0);  // httplib sets it as SO_SNDTIMEO, too
  server.set_keep_alive_timeout(options.io_timeout_s);
  const int num_threads = options.max_clients + kSpareWorkers;
  // httplib calls this once listen_after_bind() has marked the server running (so stop() from
  // here on ends the accept loop) and owns the pool it returns (hence the bare new).
  server.new_task_queue = [&impl, num_threads]() -> httplib::TaskQueue* {
    {
      std::lock_guard<std::mutex> lock(impl.mutex);
      impl.listening = true;
    }
    impl.changed.notify_all();
    return new WorkerPool(num_threads);
  };
  impl.addRoutes();

  errno = 0;
  const bool bound = options.port == 0
                         ? (impl.port = server.bind_to_any_port(options.bind_address)) > 0
                         : server.bind_to_port(options.bind_address, options.port);
  if (!bound) {
    const int bind_errno = errno;
    const std::string reason =
        bind_errno != 0 ? std::strerror(bind_errno) : "the address does not resolve";
    throw ConfigError("http: cannot listen on " + hostPort(options.bind_address, options.port) +
                      ": " + reason);
  }
  if (options.port != 0) impl.port = options.port;

  impl.listener = std::thread([&impl] { impl.listen(); });
  {
    std::unique_lock<std::mutex> lock(impl.mutex);
    impl.changed.wait(lock, [&] { return impl.listening || impl.listener_done; });
  }
  log::info("viewer: http://", hostPort(options.bind_address, impl.port), "/");
}

MjpegServer::~MjpegServer() { stop(); }

void MjpegServer::stop() {
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> stop_lock(impl.stop_mutex);
  {
    std::lock_guard<std::mutex> lock(impl.mutex);
    impl.stopping = true;
  }
  impl.changed.notify_all();  // streaming handlers return false and their connections close
  impl.server.stop();         // closes the listening socket; the listener joins the pool
  if (impl.listener.joinable()) impl.listener.join();
}

int MjpegServer::port() const { return impl_->port; }

void MjpegServer::publishJpeg(std::vector<unsigned char> jpeg) {
  auto shared = std::make_shared<const Jpeg>(std::move(jpeg));
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->latest_jpeg = std::move(shared);
    ++impl_->frame_generation;
  }
  impl_->changed.notify_all();
}

void MjpegServer::publishPose(std::string json_line) {
  LTLO_ASSERT(json_line.find_first_of("\r\n") == std::string::npos,
              "a pose line must be one line: " << json_line);
  {
    std::lock_guard<std::mutex> lock(impl_->mutex);
    impl_->recent_poses.push_back(std::move(json_line));
    if (impl_->recent_poses.size() > static_cast<std::size_t>(kPoseBacklog)) {
      impl_->recent_poses.pop_front();
    }
    ++impl_->poses_published;
  }
  impl_->changed.notify_all();
}

std::uint64_t MjpegServer::framesPublished() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->frame_generation;
}

std::uint64_t MjpegServer::posesPublished() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->poses_published;
}

int MjpegServer::streamingClients() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->streaming_clients;
}

std::uint64_t MjpegServer::framesSent() const {
  return impl_->frames_sent.load(std::memory_order_relaxed);
}

}  // namespace ltlo::http
