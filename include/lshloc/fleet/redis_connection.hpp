#pragma once
// A small synchronous Redis client over hiredis: one connection, commands as
// binary-safe argument lists, replies as plain values. What the fleet's map
// log needs (docs/fleet.md), not a general client.
// Times [s].
// Thread safety: one RedisConnection per thread; a Reply is a plain value.
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lshloc::fleet {

/// Where a Redis server listens: redis://HOST:PORT (HOST a name or address,
/// PORT 1..65535; redis://HOST means port 6379).
struct RedisAddress {
  std::string host = "127.0.0.1";
  int port = 6379;
  /// Parses a redis:// URL; throws lshloc::Error naming the URL and what was
  /// expected otherwise.
  static RedisAddress parse(const std::string& url);
  std::string url() const { return "redis://" + host + ":" + std::to_string(port); }
};

/// One reply, as RESP2 gives it.
struct Reply {
  enum class Type : std::uint8_t { kNil, kString, kStatus, kInteger, kArray, kError };
  Type type = Type::kNil;
  std::string text;  ///< kString (binary-safe), kStatus and kError (the server's message)
  long long integer = 0;
  std::vector<Reply> elements;  ///< kArray

  bool is_nil() const { return type == Type::kNil; }
  bool is_error() const { return type == Type::kError; }
};

class RedisConnection {
 public:
  /// Connects within `timeout_s`; throws lshloc::Error naming the address on
  /// failure. Commands wait at most `timeout_s` longer than any BLOCK they ask for.
  explicit RedisConnection(RedisAddress address, double timeout_s = 5.0);
  ~RedisConnection();
  RedisConnection(RedisConnection&&) noexcept;
  RedisConnection& operator=(RedisConnection&&) noexcept;

  const RedisAddress& address() const { return address_; }

  /// Runs one command (its words, binary-safe) and returns the reply. A Redis
  /// error reply throws lshloc::Error with the server's message and the
  /// command's name; a lost connection throws too (then reconnect() or a new
  /// connection).
  Reply command(std::span<const std::string_view> args);
  Reply command(std::initializer_list<std::string_view> args) {
    return command(std::span<const std::string_view>(args.begin(), args.size()));
  }
  /// Sends every command at once and reads the replies in order (one round
  /// trip for all: how mappers publish fast). Throws on the first error reply.
  std::vector<Reply> pipeline(const std::vector<std::vector<std::string>>& commands);

  /// As command() and pipeline(), but an error reply comes back as a Reply
  /// of type kError instead of throwing (what a cluster client needs to see
  /// MOVED and ASK redirects); a lost connection still throws.
  Reply exchange(std::span<const std::string_view> args);
  std::vector<Reply> exchange_all(const std::vector<std::vector<std::string>>& commands);

  /// Drops the connection and connects again (after a server restart).
  void reconnect();

 private:
  struct Context;
  void connect();
  RedisAddress address_;
  double timeout_s_;
  std::unique_ptr<Context> context_;
};

}  // namespace lshloc::fleet
