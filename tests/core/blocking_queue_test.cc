// BlockingQueue: FIFO order, capacity, close semantics, and many threads synchronised only by
// the queues themselves (no sleeps, no timing; run under TSan with LTLO_SANITIZE_THREAD).
#include "ltlo/core/blocking_queue.h"

#include <gtest/gtest.h>

#include <memory>
#include <numeric>
#include <string>
#include <thread>
#include <vector>

namespace ltlo {
namespace {

TEST(BlockingQueue, KeepsFifoOrderAndCapacity) {
  BlockingQueue<int> queue(3);
  EXPECT_EQ(queue.capacity(), 3u);
  EXPECT_TRUE(queue.tryPush(1));
  EXPECT_TRUE(queue.push(2));
  EXPECT_TRUE(queue.tryPush(3));
  EXPECT_FALSE(queue.tryPush(4));  // full: tryPush never waits
  EXPECT_EQ(queue.size(), 3u);
  EXPECT_EQ(queue.pop(), std::optional<int>(1));
  EXPECT_EQ(queue.tryPop(), std::optional<int>(2));
  EXPECT_TRUE(queue.tryPush(5));
  EXPECT_EQ(queue.pop(), std::optional<int>(3));
  EXPECT_EQ(queue.pop(), std::optional<int>(5));
  EXPECT_EQ(queue.tryPop(), std::nullopt);  // empty and open: tryPop does not wait
}

TEST(BlockingQueue, CloseDrainsThenReturnsNullopt) {
  BlockingQueue<std::string> queue(4);
  ASSERT_TRUE(queue.push("a"));
  ASSERT_TRUE(queue.push("b"));
  queue.close();
  queue.close();  // idempotent
  EXPECT_TRUE(queue.closed());
  EXPECT_FALSE(queue.push("c"));
  EXPECT_FALSE(queue.tryPush("c"));
  EXPECT_EQ(queue.pop(), std::optional<std::string>("a"));
  EXPECT_EQ(queue.pop(), std::optional<std::string>("b"));
  EXPECT_EQ(queue.pop(), std::nullopt);  // closed and drained: does not block
  EXPECT_EQ(queue.tryPop(), std::nullopt);
}

TEST(BlockingQueue, MovesOnlyTypes) {
  BlockingQueue<std::unique_ptr<int>> queue(1);
  ASSERT_TRUE(queue.push(std::make_unique<int>(42)));
  std::optional<std::unique_ptr<int>> item = queue.pop();
  ASSERT_TRUE(item.has_value());
  EXPECT_EQ(**item, 42);
}

TEST(BlockingQueue, CloseWakesBlockedConsumer) {
  BlockingQueue<int> queue(2);
  std::optional<int> popped = 7;
  std::thread consumer([&] { popped = queue.pop(); });  // blocks: empty and open
  queue.close();  // whether before or after the pop started waiting, pop must return nullopt
  consumer.join();
  EXPECT_EQ(popped, std::nullopt);
}

TEST(BlockingQueue, CloseWakesBlockedProducer) {
  BlockingQueue<int> queue(1);
  ASSERT_TRUE(queue.push(1));
  bool pushed = true;
  std::thread producer([&] { pushed = queue.push(2); });  // blocks: full
  queue.close();  // full and closed: the waiting push gives up
  producer.join();
  EXPECT_FALSE(pushed);
  EXPECT_EQ(queue.pop(), std::optional<int>(1));  // the item queued before close survives
  EXPECT_EQ(queue.pop(), std::nullopt);
}

TEST(BlockingQueue, FullQueueBlocksProducerUntilConsumerPops) {
  // Ping-pong through two capacity-1 queues: the producer can only be one item ahead, so the
  // consumer must observe every item in order and never more than `capacity` queued.
  BlockingQueue<int> data(1);
  BlockingQueue<int> acks(1);
  constexpr int kItems = 500;
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) {
      ASSERT_TRUE(data.push(i));
      ASSERT_TRUE(acks.pop().has_value());  // wait until the consumer took item i
    }
    data.close();
  });
  std::vector<int> received;
  while (std::optional<int> item = data.pop()) {
    EXPECT_LE(data.size(), data.capacity());
    received.push_back(*item);
    ASSERT_TRUE(acks.push(*item));
  }
  producer.join();
  ASSERT_EQ(received.size(), static_cast<size_t>(kItems));
  for (int i = 0; i < kItems; ++i) EXPECT_EQ(received[i], i);
}

TEST(BlockingQueue, ManyProducersAndConsumersDeliverEveryItemOnce) {
  constexpr int kProducers = 4;
  constexpr int kConsumers = 3;
  constexpr int kPerProducer = 2000;
  BlockingQueue<int> queue(8);  // small: producers block often
  std::vector<std::thread> producers;
  for (int p = 0; p < kProducers; ++p) {
    producers.emplace_back([&queue, p] {
      for (int i = 0; i < kPerProducer; ++i) ASSERT_TRUE(queue.push(p * kPerProducer + i));
    });
  }
  std::vector<std::vector<int>> per_consumer(kConsumers);
  std::vector<std::thread> consumers;
  for (int c = 0; c < kConsumers; ++c) {
    consumers.emplace_back([&queue, &per_consumer, c] {
      while (std::optional<int> item = queue.pop()) per_consumer[c].push_back(*item);
    });
  }
  for (std::thread& t : producers) t.join();
  queue.close();  // all pushes are in; consumers drain and stop
  for (std::thread& t : consumers) t.join();

  std::vector<int> seen(kProducers * kPerProducer, 0);
  for (const std::vector<int>& items : per_consumer) {
    // Each consumer sees each producer's items in the order they were pushed.
    std::vector<int> last(kProducers, -1);
    for (const int item : items) {
      ++seen[item];
      EXPECT_GT(item, last[item / kPerProducer]);
      last[item / kPerProducer] = item;
    }
  }
  for (size_t i = 0; i < seen.size(); ++i) ASSERT_EQ(seen[i], 1) << "item " << i;
}

}  // namespace
}  // namespace ltlo
