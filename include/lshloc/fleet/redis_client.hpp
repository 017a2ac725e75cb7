#pragma once
// A Redis deployment as the fleet's map log uses it: one server, or a Redis
// Cluster whose key slots this client routes itself (hiredis has no cluster
// support in Debian 12). Small on purpose: it knows the key of the commands
// the map log sends, follows MOVED and ASK redirects, and nothing more
// (docs/fleet.md "Redis Cluster").
// Times [s].
// Thread safety: one RedisClient per thread, as its RedisConnections.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "lshloc/fleet/redis_connection.hpp"

namespace lshloc::fleet {

/// Redis Cluster's hash slot of a key, 0..16383: CRC-16/XMODEM of the key, or
/// of its hash tag (the text between the first '{' and the next '}', when
/// that is not empty), modulo 16384.
std::uint16_t hash_slot(std::string_view key);

/// The key a command is routed by: the first stream after STREAMS for XREAD,
/// the first key for EVAL, else its second word (empty: no key).
std::string_view routing_key(std::span<const std::string> command);

struct RedisClientStats {
  std::size_t moved = 0;           ///< MOVED redirects followed (a slot had moved for good)
  std::size_t asked = 0;           ///< ASK redirects followed (a slot was migrating)
  std::size_t slot_refreshes = 0;  ///< times the slot table was read (CLUSTER SLOTS)
};

class RedisClient {
 public:
  /// Connects to `seed` within `timeout_s` and asks it for the cluster's slot
  /// table; a server without cluster support is used as the one server.
  /// Throws lshloc::Error naming the address on failure.
  explicit RedisClient(RedisAddress seed, double timeout_s = 5.0);
  ~RedisClient();
  RedisClient(RedisClient&&) noexcept;
  RedisClient& operator=(RedisClient&&) noexcept;

  /// The address it was given (messages name it).
  const RedisAddress& address() const { return seed_; }
  bool is_cluster() const { return cluster_; }
  /// The nodes it knows, the seed first: the masters serving slots (one
  /// without a cluster).
  std::vector<RedisAddress> nodes() const { return nodes_; }
  /// The node index serving `key` (0 without a cluster).
  std::size_t node_of(std::string_view key) const;

  /// Runs one command on the node serving its routing_key(), following
  /// redirects. An error reply throws lshloc::Error with the server's message.
  Reply command(std::span<const std::string_view> args);
  Reply command(std::initializer_list<std::string_view> args) {
    return command(std::span<const std::string_view>(args.begin(), args.size()));
  }
  /// Sends the commands, each node's share pipelined in one round trip, and
  /// returns the replies in the commands' order; commands that were
  /// redirected run again, in their order, on the node the redirect names.
  /// Commands on one key keep their order. Throws on the first error reply.
  std::vector<Reply> pipeline(const std::vector<std::vector<std::string>>& commands);

  /// Drops every connection and reads the slot table again from the seed (or
  /// any node it knew): after a server restart.
  void reconnect();
  const RedisClientStats& stats() const { return stats_; }

 private:
  Reply run(std::vector<std::string> command);
  bool read_slots(RedisConnection& from);
  void apply_slots(const Reply& slots, const RedisAddress& from);
  std::size_t node_index(const RedisAddress& a);
  RedisConnection& connection(std::size_t node);
  std::size_t node_of_slot(std::uint16_t slot) const;

  static constexpr std::size_t kSlots = 16384;
  static constexpr std::uint16_t kNoNode = 0xffff;
  RedisAddress seed_;
  double timeout_s_;
  bool cluster_ = false;
  std::vector<RedisAddress> nodes_;
  std::vector<std::unique_ptr<RedisConnection>> connections_;  ///< per node, opened when first used
  std::unique_ptr<std::array<std::uint16_t, kSlots>> slot_node_;
  RedisClientStats stats_;
};

}  // namespace lshloc::fleet
