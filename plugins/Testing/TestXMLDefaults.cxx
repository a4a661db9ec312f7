// The panel's defaults (default_values in the server-manager XML) are the source's own, which
// come from rvegen::default_scene(): a fresh vtkRVEGenerator printed (PrintSelf) must show every
// XML property's default. Also proves PrintSelf names every property the panel sets.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "vtkNew.h"
#include "vtkRVEGenerator.h"

namespace {

std::vector<std::string> tokens(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  for (std::string t; in >> t;) out.push_back(t);
  return out;
}

bool same(const std::string& a, const std::string& b) {
  if (a == b) return true;
  char* ea = nullptr;
  char* eb = nullptr;
  const double x = std::strtod(a.c_str(), &ea), y = std::strtod(b.c_str(), &eb);
  if (*ea || *eb) return false;
  return std::abs(x - y) <= 1e-12 * std::max(1.0, std::abs(x));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: TestXMLDefaults RVEGenerator.xml\n";
    return 2;
  }
  std::ifstream in(argv[1]);
  std::stringstream xml;
  xml << in.rdbuf();
  // The generator's proxy only (the file also holds the other filters' proxies).
  const std::string all = xml.str();
  const size_t begin = all.find("class=\"vtkRVEGenerator\"");
  const size_t end = all.find("</SourceProxy>", begin);
  if (begin == std::string::npos || end == std::string::npos) {
    std::cerr << "no vtkRVEGenerator proxy in " << argv[1] << "\n";
    return 1;
  }
  const std::string text = all.substr(begin, end - begin);

  vtkNew<vtkRVEGenerator> source;
  std::ostringstream printed;
  printed.precision(17);
  source->Print(printed);
  std::map<std::string, std::string> values;  // "Key: value" lines of PrintSelf
  {
    std::istringstream lines(printed.str());
    const std::regex line(R"(^\s*([A-Za-z]+):\s?(.*)$)");
    std::smatch m;
    for (std::string l; std::getline(lines, l);) {
      if (std::regex_match(l, m, line)) values[m[1]] = m[2];
    }
  }

  // Opening tags of the source proxy's properties that set a value.
  const std::regex tag(R"(<(Int|Double|String)VectorProperty\b([^>]*)>)");
  const std::regex command(R"re(command="Set([A-Za-z]+)")re");
  const std::regex defaults(R"re(default_values="([^"]*)")re");
  int checked = 0, failed = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), tag); it != std::sregex_iterator();
       ++it) {
    const std::string attrs = (*it)[2];
    std::smatch c, d;
    if (!std::regex_search(attrs, c, command) || !std::regex_search(attrs, d, defaults)) continue;
    const std::string name = c[1];
    const auto found = values.find(name);
    if (found == values.end()) {
      std::cerr << name << ": in the XML, not printed by PrintSelf\n";
      ++failed;
      continue;
    }
    std::vector<std::string> want = tokens(d[1]), got = tokens(found->second);
    if (name == "SceneFile" && want.empty() && got == std::vector<std::string>{"(none)"}) {
      got.clear();
    }
    if (name == "Method" && got.size() == 2) got.resize(1);  // "0 (md)"
    bool ok = want.size() == got.size();
    for (size_t k = 0; ok && k < want.size(); ++k) ok = same(want[k], got[k]);
    if (!ok) {
      std::cerr << name << ": XML default \"" << d[1] << "\", source default \"" << found->second
                << "\"\n";
      ++failed;
    }
    ++checked;
  }
  std::cout << checked << " XML defaults checked against the source, " << failed << " differ\n";
  return failed == 0 && checked >= 30 ? 0 : 1;
}
