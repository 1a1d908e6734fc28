// Every option of `theia render` is declared once, beside the struct that
// holds it, by a declare_options(v, options) function:
//
//   template <class V> void declare_options(V& v, SDTreeOptions& o) {
//     v.image("spatial_threshold", o.spatial_threshold, "SD-tree: split a spatial leaf ...");
//   }
//
// The visitor V is one of the three below: the command line binds a flag to
// the field (its default is the struct's), the log writes the value, the
// checkpoint fingerprint hashes it.  What the declaration says about an option
// is which of three it is:
//   image   changes the image: part of the fingerprint, so a checkpoint
//           written with one value is never resumed with another;
//   order   changes only floating-point summation order (threads, batch and
//           pool sizes, sorting): a render may resume with another value;
//   output  changes where or when state is written, never the image.
// Adding an option is adding a field and its one declaration line.
//
// One name: an option's name is its field's name within its group (the
// feature that owns the struct).  The flag is the kebab-case of
// GROUP_FIELD and the log key log["options"]["GROUP_FIELD"]; a group's
// `enabled` field is the group itself (--guiding, options.guiding); the
// render's own options have no group (--spp, options.spp).  So
// SDTreeOptions::spatial_threshold in group "guiding" is
// --guiding-spatial-threshold and options.guiding_spatial_threshold.
#pragma once

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <string>
#include <type_traits>
#include <vector>

namespace theia {

// snake_case: GROUP_FIELD, the group alone for `enabled`, the field alone without a group.
inline std::string option_name(const std::string& group, const std::string& field) {
  if (group.empty()) return field;
  return field == "enabled" ? group : group + "_" + field;
}

inline std::string option_flag(const std::string& group, const std::string& field) {
  std::string flag = "--" + option_name(group, field);
  for (char& ch : flag) ch = ch == '_' ? '-' : ch;
  return flag;
}

// A feature that is on, off, or decides for itself (--guiding, --no-guiding,
// --guiding-auto): three flags, none of which takes the next argument.
enum class OnOffAuto { Off, On, Auto };
inline const char* to_string(OnOffAuto v) { return v == OnOffAuto::Off ? "off" : v == OnOffAuto::On ? "on" : "auto"; }

// Visitors set `group` before declaring a struct's options (declare_render_options, app/render.h).
struct OptionVisitor {
  std::string group;
};

// No option takes a negative number.  Counts, sizes, seeds, depths, limits
// and probabilities are never negative, and a default that means "not given"
// (-1: the scene's spp and maximum depth, the schedule's iteration sizes, off)
// is not a value to type: `--spp -1` is refused, never taken as the default.
// CLI11 names the flag: "--spp: must not be negative, got -1 ...".
inline CLI::Validator non_negative_number() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(value, v) || !(v < 0.0)) return {};
        return "must not be negative, got " + value + " (leave the option out for its default)";
      },
      "", "non-negative");
}

// Binds each option to a flag.  A bool that defaults to on, or that only
// tunes how the render runs (an `order` option: --sort), is a switch
// (--caustics / --no-caustics, --sort on|off); any other is a flag
// (--guiding), which never takes the next argument as its value.  A number
// must not be negative (non_negative_number); a default that is one (a "not
// given" -1) is not shown as the default.
struct OptionBinder : OptionVisitor {
  CLI::App& app;
  explicit OptionBinder(CLI::App& a) : app(a) {}

  template <class T>
  void image(const char* name, T& field, const char* help) { bind(name, field, help, false); }
  template <class T>
  void order(const char* name, T& field, const char* help) { bind(name, field, help, true); }
  template <class T>
  void output(const char* name, T& field, const char* help) { bind(name, field, help, false); }

 private:
  template <class T>
  void bind(const char* name, T& field, const char* help, bool tuning) {
    const std::string flag = option_flag(group, name);
    if constexpr (std::is_same_v<T, OnOffAuto>) {
      auto set = [&field](OnOffAuto v) { return [&field, v] { field = v; }; };
      const std::string was = std::string(" (default: ") + to_string(field) + ")";
      app.add_flag_callback(flag, set(OnOffAuto::On), std::string(help) + was);
      app.add_flag_callback("--no-" + flag.substr(2), set(OnOffAuto::Off), "Off" + was);
      app.add_flag_callback(flag + "-auto", set(OnOffAuto::Auto), "Decides for itself" + was);
    } else if constexpr (std::is_same_v<T, bool>) {
      if (field || tuning)
        app.add_flag(flag + ",!--no-" + flag.substr(2), field,
                     std::string(help) + (field ? " (default: on)" : " (default: off)"))
            ->expected(0, 1);
      else
        app.add_flag(flag, field, help);
    } else if constexpr (std::is_arithmetic_v<T>) {
      CLI::Option* option = app.add_option(flag, field, help)->check(non_negative_number());
      if (!std::signbit(double(field))) option->capture_default_str();
    } else {
      app.add_option(flag, field, help)->capture_default_str();
    }
  }
};

// log["options"]: every option under its one name (the image options alone
// with image_only: what a split frame's parts must agree on, farm/part.h).
struct OptionLog : OptionVisitor {
  nlohmann::json json = nlohmann::json::object();
  bool image_only = false;

  template <class T>
  void image(const char* name, const T& field, const char*) { json[option_name(group, name)] = loggable(field); }
  template <class T>
  void order(const char* name, const T& field, const char*) {
    if (!image_only) json[option_name(group, name)] = loggable(field);
  }
  template <class T>
  void output(const char* name, const T& field, const char*) {
    if (!image_only) json[option_name(group, name)] = loggable(field);
  }

 private:
  template <class T>
  static auto loggable(const T& field) {
    if constexpr (std::is_same_v<T, OnOffAuto>) return std::string(to_string(field));
    else return field;
  }
};

// The text the options fingerprint hashes: NAME=VALUE; for every image option.
struct OptionFingerprintText : OptionVisitor {
  std::string text;

  template <class T>
  void image(const char* name, const T& field, const char*) {
    if constexpr (std::is_same_v<T, OnOffAuto>) text += fmt::format("{}={};", option_name(group, name), to_string(field));
    else text += fmt::format("{}={};", option_name(group, name), field);
  }
  template <class T>
  void order(const char*, const T&, const char*) {}
  template <class T>
  void output(const char*, const T&, const char*) {}
};

// The flags of each kind (tests: every image option refuses a resume, every
// order option resumes), and those that take a number (every one refuses a negative).
struct OptionFlags : OptionVisitor {
  std::vector<std::string> image_flags, order_flags, output_flags, number_flags;

  template <class T>
  void image(const char* name, const T&, const char*) { add(image_flags, name, T{}); }
  template <class T>
  void order(const char* name, const T&, const char*) { add(order_flags, name, T{}); }
  template <class T>
  void output(const char* name, const T&, const char*) { add(output_flags, name, T{}); }

 private:
  template <class T>
  void add(std::vector<std::string>& kind, const char* name, const T&) {
    kind.push_back(option_flag(group, name));
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) number_flags.push_back(kind.back());
  }
};

}  // namespace theia
