// A CSV read as columns by name, for tests that read kinegen's output.
#pragma once

#include <cstdlib>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace kinegen::test {

// The header's names, each with its column. strtod, not stod: "nan" and subnormal values (the
// noise of a coordinate that is 0) are values too.
inline std::map<std::string, std::vector<double>> csv_columns(const std::string& csv) {
  std::istringstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> names;
  std::istringstream header(line);
  for (std::string n; std::getline(header, n, ',');) names.push_back(n);
  std::map<std::string, std::vector<double>> out;
  while (std::getline(in, line)) {
    std::istringstream row(line);
    std::size_t k = 0;
    for (std::string v; std::getline(row, v, ','); ++k)
      out[names.at(k)].push_back(std::strtod(v.c_str(), nullptr));
  }
  return out;
}

}  // namespace kinegen::test
