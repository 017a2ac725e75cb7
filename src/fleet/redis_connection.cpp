#include "lshloc/fleet/redis_connection.hpp"

#include <hiredis/hiredis.h>
#include <sys/time.h>

#include <charconv>
#include <cmath>

#include "lshloc/common/error.hpp"

namespace lshloc::fleet {

namespace {

timeval to_timeval(double seconds) {
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(seconds);
  tv.tv_usec = static_cast<suseconds_t>((seconds - std::floor(seconds)) * 1e6);
  return tv;
}

Reply convert(const redisReply* r) {
  Reply out;
  switch (r->type) {
    case REDIS_REPLY_STRING:
      out.type = Reply::Type::kString, out.text.assign(r->str, r->len);
      break;
    case REDIS_REPLY_STATUS:
      out.type = Reply::Type::kStatus, out.text.assign(r->str, r->len);
      break;
    case REDIS_REPLY_INTEGER:
      out.type = Reply::Type::kInteger, out.integer = r->integer;
      break;
    case REDIS_REPLY_ERROR:
      out.type = Reply::Type::kError, out.text.assign(r->str, r->len);
      break;
    case REDIS_REPLY_ARRAY:
      out.type = Reply::Type::kArray;
      out.elements.reserve(r->elements);
      for (std::size_t i = 0; i < r->elements; ++i) out.elements.push_back(convert(r->element[i]));
      break;
    default:
      out.type = Reply::Type::kNil;
  }
  return out;
}

}  // namespace

RedisAddress RedisAddress::parse(const std::string& url) {
  constexpr std::string_view scheme = "redis://";
  auto bad = [&](const std::string& what) {
    return Error("Redis address '" + url + "': expected redis://HOST[:PORT]; " + what);
  };
  if (!std::string_view(url).starts_with(scheme)) throw bad("it does not start with redis://");
  std::string_view rest = std::string_view(url).substr(scheme.size());
  if (!rest.empty() && rest.back() == '/') rest.remove_suffix(1);
  RedisAddress a;
  const std::size_t colon = rest.rfind(':');
  a.host = std::string(rest.substr(0, colon));
  if (a.host.empty()) throw bad("no host");
  if (colon != std::string_view::npos) {
    const std::string_view port = rest.substr(colon + 1);
    int p = 0;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), p);
    if (ec != std::errc() || end != port.data() + port.size() || p < 1 || p > 65535)
      throw bad("a port of 1..65535, got '" + std::string(port) + "'");
    a.port = p;
  }
  return a;
}

struct RedisConnection::Context {
  redisContext* c = nullptr;
  ~Context() {
    if (c) redisFree(c);
  }
};

RedisConnection::RedisConnection(RedisAddress address, double timeout_s)
    : address_(std::move(address)), timeout_s_(timeout_s) {
  connect();
}
RedisConnection::~RedisConnection() = default;
RedisConnection::RedisConnection(RedisConnection&&) noexcept = default;
RedisConnection& RedisConnection::operator=(RedisConnection&&) noexcept = default;

void RedisConnection::connect() {
  auto ctx = std::make_unique<Context>();
  ctx->c = redisConnectWithTimeout(address_.host.c_str(), address_.port, to_timeval(timeout_s_));
  if (ctx->c == nullptr) throw Error(address_.url() + ": cannot connect (out of memory)");
  if (ctx->c->err) throw Error(address_.url() + ": cannot connect: " + ctx->c->errstr);
  // A blocking read waits for its BLOCK time plus this margin at most.
  redisSetTimeout(ctx->c, to_timeval(timeout_s_));
  context_ = std::move(ctx);
}

void RedisConnection::reconnect() {
  context_.reset();
  connect();
}

Reply RedisConnection::exchange(std::span<const std::string_view> args) {
  if (!context_) throw Error(address_.url() + ": not connected");
  std::vector<const char*> argv;
  std::vector<std::size_t> lens;
  for (const auto& a : args) argv.push_back(a.data()), lens.push_back(a.size());
  auto* r =
      static_cast<redisReply*>(redisCommandArgv(context_->c, static_cast<int>(argv.size()), argv.data(), lens.data()));
  if (r == nullptr) {
    const std::string why = context_->c->errstr;
    context_.reset();  // hiredis cannot reuse a context after an I/O error
    throw Error(address_.url() + ": " + (args.empty() ? "" : std::string(args[0])) + " failed: " + why);
  }
  std::unique_ptr<redisReply, void (*)(void*)> owned(r, freeReplyObject);
  return convert(r);
}

Reply RedisConnection::command(std::span<const std::string_view> args) {
  Reply r = exchange(args);
  if (r.is_error()) throw Error(address_.url() + ": " + (args.empty() ? "" : std::string(args[0])) + ": " + r.text);
  return r;
}

std::vector<Reply> RedisConnection::exchange_all(const std::vector<std::vector<std::string>>& commands) {
  if (!context_) throw Error(address_.url() + ": not connected");
  for (const auto& cmd : commands) {
    std::vector<const char*> argv;
    std::vector<std::size_t> lens;
    for (const auto& a : cmd) argv.push_back(a.data()), lens.push_back(a.size());
    if (redisAppendCommandArgv(context_->c, static_cast<int>(argv.size()), argv.data(), lens.data()) != REDIS_OK)
      throw Error(address_.url() + ": cannot queue " + (cmd.empty() ? "" : cmd[0]) + ": " + context_->c->errstr);
  }
  std::vector<Reply> replies;
  replies.reserve(commands.size());
  for (std::size_t i = 0; i < commands.size(); ++i) {
    void* raw = nullptr;
    if (redisGetReply(context_->c, &raw) != REDIS_OK || raw == nullptr) {
      const std::string why = context_->c->errstr;
      context_.reset();
      throw Error(address_.url() + ": pipelined " + commands[i].front() + " failed: " + why);
    }
    std::unique_ptr<redisReply, void (*)(void*)> owned(static_cast<redisReply*>(raw), freeReplyObject);
    replies.push_back(convert(owned.get()));
  }
  return replies;
}

std::vector<Reply> RedisConnection::pipeline(const std::vector<std::vector<std::string>>& commands) {
  std::vector<Reply> replies = exchange_all(commands);
  for (std::size_t i = 0; i < replies.size(); ++i)
    if (replies[i].is_error()) throw Error(address_.url() + ": " + commands[i].front() + ": " + replies[i].text);
  return replies;
}

}  // namespace lshloc::fleet
