#include "rvegen/io/json_util.hpp"

#include <set>
#include <utility>

namespace rvegen::json_util {
namespace {

// Builds the document from nlohmann's SAX events, refusing a key given twice and keeping the
// path to the current value for messages. (nlohmann's callback parser does the same bookkeeping
// but scans the whole parent at every closing brace: quadratic in the length of an array.)
class StrictBuilder {
 public:
  /// No input of rvegen nests deeper; deeper documents are refused before they exhaust the
  /// stack of the code that walks them.
  static constexpr size_t kMaxDepth = 256;
  Json root;

  bool null() { return put(nullptr); }
  bool boolean(bool v) { return put(v); }
  bool number_integer(Json::number_integer_t v) { return put(v); }
  bool number_unsigned(Json::number_unsigned_t v) { return put(v); }
  bool number_float(Json::number_float_t v, const std::string&) { return put(v); }
  bool string(std::string& v) { return put(std::move(v)); }
  bool binary(Json::binary_t&) { return false; }  // not produced by JSON text
  bool start_object(std::size_t) { return open(Json::object(), false); }
  bool start_array(std::size_t) { return open(Json::array(), true); }
  bool end_object() { return close(); }
  bool end_array() { return close(); }
  bool key(std::string& k) {
    Frame& f = frames_.back();
    f.key = k;
    if (!f.keys.insert(k).second) throw InputError(where() + ": key given twice");
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception& e) {
    error_ = e.what();
    return false;
  }
  const std::string& error() const { return error_; }

  std::string where() const {
    std::string at;
    for (size_t k = 0; k < frames_.size(); ++k) {
      const Frame& f = frames_[k];
      if (f.array) {
        // The elements completed: all but an open last one.
        const size_t done = f.value->size() - (k + 1 < frames_.size() ? 1 : 0);
        at += "[" + std::to_string(done) + "]";
      } else if (!f.key.empty()) {
        at += (at.empty() ? "" : ".") + f.key;
      }
    }
    return at.empty() ? std::string("(root)") : at;
  }

 private:
  struct Frame {
    Json* value;
    bool array;
    std::string key;
    std::set<std::string> keys;
  };

  // The slot the next value goes to: the root, the next element of an array, or the member
  // of the current key. Containers on the stack are never moved while open: an array grows only
  // after its open child closed, and std::map members keep their address.
  Json* slot() {
    if (frames_.empty()) return &root;
    Frame& f = frames_.back();
    if (f.array) {
      f.value->push_back(nullptr);
      return &f.value->back();
    }
    return &(*f.value)[f.key];
  }
  template <class V>
  bool put(V&& v) {
    *slot() = std::forward<V>(v);
    return true;
  }
  bool open(Json&& empty, bool array) {
    if (frames_.size() >= kMaxDepth)
      throw InputError(where().substr(0, 60) + "...: nested deeper than " +
                       std::to_string(kMaxDepth) + " levels");
    Json* s = slot();
    *s = std::move(empty);
    frames_.push_back({s, array, {}, {}});
    return true;
  }
  bool close() {
    frames_.pop_back();
    return true;
  }

  std::vector<Frame> frames_;
  std::string error_;
};

// The JSON library's message without its own tag ("[json.exception.parse_error.101] ").
std::string plain(const std::string& message) {
  if (message.rfind("[json.exception.", 0) != 0) return message;
  const size_t end = message.find("] ");
  return end == std::string::npos ? message : message.substr(end + 2);
}

}  // namespace

Json parse(const std::string& text, const std::string& what) {
  StrictBuilder b;
  bool ok = false;
  try {
    ok = Json::sax_parse(text, &b);
  } catch (const Json::exception& e) {
    throw InputError(what + ": not valid JSON at " + b.where() + " (" + plain(e.what()) + ")");
  }
  if (!ok)
    throw InputError(what + ": not valid JSON at " + b.where() + " (" + plain(b.error()) + ")");
  return std::move(b.root);
}

}  // namespace rvegen::json_util
