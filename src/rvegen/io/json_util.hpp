// Strict reading helpers over nlohmann::json: every error names the key path.
#pragma once

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "rvegen/model/inclusion_set.hpp"

namespace rvegen::json_util {

using Json = nlohmann::json;

inline std::string join(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

[[noreturn]] inline void fail(const std::string& path, const std::string& what) {
  throw InputError(path + ": " + what);
}

inline const Json& require(const Json& obj, const char* key, const std::string& path) {
  if (!obj.is_object()) fail(path, "expected an object");
  auto it = obj.find(key);
  if (it == obj.end()) fail(join(path, key), "missing key");
  return *it;
}

/// Rejects keys not in `allowed`.
/// Edit distance (insertions, deletions, substitutions) between two short keys.
inline size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t k = 0; k <= b.size(); ++k) row[k] = k;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diag = row[0];
    row[0] = i;
    for (size_t k = 1; k <= b.size(); ++k) {
      const size_t up = row[k];
      row[k] = std::min({row[k] + 1, row[k - 1] + 1, diag + (a[i - 1] == b[k - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

/// ` (did you mean "x"?)` with the nearest of `known` to `word` when one is close (at most a
/// third of its letters differ), else "": for unknown keys, outputs, commands and options.
inline std::string did_you_mean(const std::string& word, const std::vector<std::string>& known) {
  std::string nearest;
  size_t best = word.size() / 3 + 1;
  for (const std::string& k : known) {
    const size_t d = edit_distance(word, k);
    if (d < best) best = d, nearest = k;
  }
  return nearest.empty() ? "" : " (did you mean \"" + nearest + "\"?)";
}
inline std::string did_you_mean(const std::string& word, std::initializer_list<const char*> known) {
  return did_you_mean(word, std::vector<std::string>(known.begin(), known.end()));
}

/// Fails on the first key of `obj` not in `allowed`, naming it, suggesting the nearest allowed
/// key when one is close (did_you_mean), and listing the allowed keys.
inline void only_keys(const Json& obj, std::initializer_list<const char*> allowed,
                      const std::string& path) {
  if (!obj.is_object()) fail(path, "expected an object");
  for (auto it = obj.begin(); it != obj.end(); ++it) {
    bool ok = false;
    for (const char* a : allowed) ok |= it.key() == a;
    if (ok) continue;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    fail(join(path, it.key()),
         "unknown key" + did_you_mean(it.key(), allowed) + "; known keys here: " + list);
  }
}

inline double number(const Json& v, const std::string& path) {
  if (!v.is_number()) fail(path, "expected a number");
  const double x = v.get<double>();
  if (!std::isfinite(x)) fail(path, "must be finite");
  return x;
}

inline double positive(const Json& v, const std::string& path) {
  const double x = number(v, path);
  if (!(x > 0.0)) fail(path, "must be positive (got " + v.dump() + ")");
  return x;
}

inline Vec3 vec3(const Json& v, const std::string& path) {
  if (!v.is_array() || v.size() != 3) fail(path, "expected an array of 3 numbers");
  return Vec3(number(v[0], path + "[0]"), number(v[1], path + "[1]"), number(v[2], path + "[2]"));
}

/// A direction: any finite non-zero vector, normalised (scaled first, so huge or tiny
/// components do not overflow or underflow).
inline Vec3 unit_vector(const Json& v, const std::string& path) {
  Vec3 u = vec3(v, path);
  const double big = u.cwiseAbs().maxCoeff();
  if (!(big > 0.0)) fail(path, "must be non-zero");
  u /= big;
  return u.normalized();
}

inline bool boolean(const Json& v, const std::string& path) {
  if (!v.is_boolean()) fail(path, "expected true or false");
  return v.get<bool>();
}

inline std::string string(const Json& v, const std::string& path) {
  if (!v.is_string()) fail(path, "expected a string");
  return v.get<std::string>();
}

/// A box object: "size" (positive), optional "origin" (default 0) and "periodic" (default true).
inline Box box(const Json& j, const std::string& path) {
  only_keys(j, {"origin", "size", "periodic"}, path);
  Box b;
  if (j.contains("origin")) b.origin = vec3(j["origin"], path + ".origin");
  b.size = vec3(require(j, "size", path), path + ".size");
  for (int k = 0; k < 3; ++k) {
    if (!(b.size[k] > 0.0)) fail(path + ".size[" + std::to_string(k) + "]", "must be positive");
  }
  if (j.contains("periodic")) b.periodic = boolean(j["periodic"], path + ".periodic");
  check_box(b, path);
  return b;
}

/// Parses JSON text strictly: a key given twice in one object is an error (JSON parsers
/// otherwise keep one of them silently), and every error names where in the document it is
/// (for example "box.size[0]"). Linear in the text (an inclusion file of a million entries
/// included).
Json parse(const std::string& text, const std::string& what);

}  // namespace rvegen::json_util
