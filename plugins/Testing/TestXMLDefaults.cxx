// The panels' defaults (default_values in the server-manager XML) are the algorithms' own, which
// come from rvegen::default_scene() and the core's option structs: a fresh instance of each proxy's
// class printed (PrintSelf) must show every XML property's default. Also proves PrintSelf names
// every property the panel sets.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "vtkNew.h"
#include "vtkRVEEffectiveProperties.h"
#include "vtkRVEGenerator.h"
#include "vtkRVEStatistics.h"
#include "vtkRVETetMesh.h"
#include "vtkRVEVoxelize.h"

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

// Checks the XML defaults of the proxy of class `cls` against `algorithm`'s PrintSelf. Returns
// the number of properties checked (-1 when the proxy is missing); `failed` counts mismatches.
int check_proxy(const std::string& all, const std::string& cls, vtkObject* algorithm, int* failed) {
  const size_t begin = all.find("class=\"" + cls + "\"");
  const size_t end = all.find("</SourceProxy>", begin);
  if (begin == std::string::npos || end == std::string::npos) {
    std::cerr << "no " << cls << " proxy in the XML\n";
    return -1;
  }
  const std::string text = all.substr(begin, end - begin);

  std::ostringstream printed;
  printed.precision(17);
  algorithm->Print(printed);
  std::map<std::string, std::string> values;  // "Key: value" lines of PrintSelf
  {
    std::istringstream lines(printed.str());
    const std::regex line(R"(^\s*([A-Za-z]+):\s?(.*)$)");
    std::smatch m;
    for (std::string l; std::getline(lines, l);) {
      if (std::regex_match(l, m, line)) values[m[1]] = m[2];
    }
  }

  // Opening tags of the proxy's properties that set a value.
  const std::regex tag(R"(<(Int|Double|String)VectorProperty\b([^>]*)>)");
  const std::regex command(R"re(command="Set([A-Za-z]+)")re");
  const std::regex defaults(R"re(default_values="([^"]*)")re");
  int checked = 0;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), tag); it != std::sregex_iterator();
       ++it) {
    const std::string attrs = (*it)[2];
    std::smatch c, d;
    if (!std::regex_search(attrs, c, command) || !std::regex_search(attrs, d, defaults)) continue;
    const std::string name = c[1];
    const auto found = values.find(name);
    ++checked;
    if (found == values.end()) {
      std::cerr << cls << "." << name << ": in the XML, not printed by PrintSelf\n";
      ++*failed;
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
      std::cerr << cls << "." << name << ": XML default \"" << d[1] << "\", source default \""
                << found->second << "\"\n";
      ++*failed;
    }
  }
  std::cout << cls << ": " << checked << " XML defaults checked\n";
  return checked;
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
  const std::string all = xml.str();
  vtkNew<vtkRVEGenerator> generator;
  vtkNew<vtkRVEVoxelize> voxelize;
  vtkNew<vtkRVETetMesh> tet_mesh;
  vtkNew<vtkRVEStatistics> statistics;
  vtkNew<vtkRVEEffectiveProperties> effective;
  // Each proxy with the least number of properties it must have checked (a regex that stopped
  // matching would otherwise pass with none).
  const struct {
    const char* cls;
    vtkObject* algorithm;
    int least;
  } proxies[] = {{"vtkRVEGenerator", generator, 30},
                 {"vtkRVEVoxelize", voxelize, 3},
                 {"vtkRVETetMesh", tet_mesh, 8},
                 {"vtkRVEStatistics", statistics, 0},
                 {"vtkRVEEffectiveProperties", effective, 5}};
  int failed = 0;
  for (const auto& p : proxies) {
    const int checked = check_proxy(all, p.cls, p.algorithm, &failed);
    if (checked < p.least) {
      std::cerr << p.cls << ": " << checked << " properties checked, at least " << p.least
                << " expected\n";
      ++failed;
    }
  }
  // RVE Effective Properties' Materials: a JSON text, so its default is single-quoted in the
  // XML (with &#10; for its line breaks) and is compared whole, character for character.
  {
    const std::regex materials(R"re(command="SetMaterials"[^>]*default_values='([^']*)')re");
    std::smatch m;
    if (!std::regex_search(all, m, materials)) {
      std::cerr << "vtkRVEEffectiveProperties.Materials: no default_values in the XML\n";
      ++failed;
    } else {
      std::string want = m[1];
      for (const auto& [entity, text] : std::vector<std::pair<std::string, std::string>>{
               {"&#10;", "\n"}, {"&quot;", "\""}, {"&lt;", "<"}, {"&gt;", ">"}, {"&amp;", "&"}}) {
        for (size_t at = want.find(entity); at != std::string::npos;
             at = want.find(entity, at + text.size())) {
          want.replace(at, entity.size(), text);
        }
      }
      if (want != effective->GetMaterials()) {
        std::cerr << "vtkRVEEffectiveProperties.Materials: XML default\n"
                  << want << "\nsource default\n"
                  << effective->GetMaterials() << "\n";
        ++failed;
      } else {
        std::cout << "vtkRVEEffectiveProperties: Materials checked\n";
      }
    }
  }
  std::cout << failed << " differ\n";
  return failed == 0 ? 0 : 1;
}
