#include "mobmap/gp/rule_table.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace mobmap::gp {
namespace {

void checkEdges(const std::vector<double>& edges, const char* what) {
  if (edges.empty()) {
    throw std::invalid_argument(std::string("RuleTable: no ") + what + " bins");
  }
  for (std::size_t i = 0; i < edges.size(); ++i) {
    if (!std::isfinite(edges[i]) || edges[i] < 0.0) {
      std::ostringstream msg;
      msg << "RuleTable: " << what << " edge " << i << " is " << edges[i]
          << " (must be finite and >= 0)";
      throw std::invalid_argument(msg.str());
    }
    if (i > 0 && !(edges[i] > edges[i - 1])) {
      std::ostringstream msg;
      msg << "RuleTable: " << what << " edges must increase strictly, but edge " << i << " ("
          << edges[i] << ") follows " << edges[i - 1];
      throw std::invalid_argument(msg.str());
    }
  }
}

int binOf(const std::vector<double>& edges, double x) {
  // upper_bound: first edge strictly greater than x; the bin is the one before it.
  const auto it = std::upper_bound(edges.begin(), edges.end(), x);
  const auto index = static_cast<int>(it - edges.begin()) - 1;
  return std::max(index, 0);
}

void checkInput(double x, const char* what) {
  if (!std::isfinite(x) || x < 0.0) {
    std::ostringstream msg;
    msg << "RuleTable::lookup: " << what << " must be finite and >= 0, got " << x;
    throw std::invalid_argument(msg.str());
  }
}

std::vector<std::string> splitCells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) {
    const auto b = cell.find_first_not_of(" \t\r");
    const auto e = cell.find_last_not_of(" \t\r");
    cells.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
  }
  if (!line.empty() && line.back() == ',') cells.emplace_back();
  return cells;
}

double parseNumber(const std::string& cell, int line_no) {
  std::size_t used = 0;
  double value = std::numeric_limits<double>::quiet_NaN();
  try {
    value = std::stod(cell, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != cell.size() || !std::isfinite(value)) {
    std::ostringstream msg;
    msg << "line " << line_no << ": '" << cell << "' is not a finite number";
    throw std::invalid_argument(msg.str());
  }
  return value;
}

}  // namespace

RuleTable::RuleTable(std::vector<double> slope_lower_edges_deg,
                     std::vector<double> roughness_lower_edges, Eigen::MatrixXd values)
    : slope_edges_deg_(std::move(slope_lower_edges_deg)),
      roughness_edges_(std::move(roughness_lower_edges)),
      values_(std::move(values)) {
  checkEdges(slope_edges_deg_, "slope");
  checkEdges(roughness_edges_, "roughness");
  if (values_.rows() != static_cast<Eigen::Index>(roughness_edges_.size()) ||
      values_.cols() != static_cast<Eigen::Index>(slope_edges_deg_.size())) {
    std::ostringstream msg;
    msg << "RuleTable: values are " << values_.rows() << "x" << values_.cols() << " but there are "
        << roughness_edges_.size() << " roughness bins and " << slope_edges_deg_.size()
        << " slope bins";
    throw std::invalid_argument(msg.str());
  }
  for (Eigen::Index r = 0; r < values_.rows(); ++r) {
    for (Eigen::Index c = 0; c < values_.cols(); ++c) {
      const double v = values_(r, c);
      if (!(v >= 0.0 && v <= 1.0)) {
        std::ostringstream msg;
        msg << "RuleTable: value at roughness bin " << r << ", slope bin " << c << " is " << v
            << " (must be in [0,1])";
        throw std::invalid_argument(msg.str());
      }
    }
  }
}

RuleTable RuleTable::paper() {
  Eigen::MatrixXd v(7, 5);
  // clang-format off
  v << 1.00, 0.75, 0.50, 0.25, 0.00,
       0.75, 0.50, 0.25, 0.00, 0.00,
       0.50, 0.25, 0.00, 0.00, 0.00,
       0.25, 0.00, 0.00, 0.00, 0.00,
       0.00, 0.00, 0.00, 0.00, 0.00,
       0.00, 0.00, 0.00, 0.00, 0.00,
       0.00, 0.00, 0.00, 0.00, 0.00;
  // clang-format on
  return RuleTable({0, 10, 20, 30, 40}, {1.0, 1.2, 1.4, 1.6, 1.8, 2.0, 2.2}, v);
}

RuleTable RuleTable::parseCsv(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  std::vector<double> slope_edges;
  std::vector<double> roughness_edges;
  std::vector<std::vector<double>> rows;
  bool have_header = false;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto cells = splitCells(line);
    if (!have_header) {
      if (cells.size() < 2) {
        throw std::invalid_argument("line " + std::to_string(line_no) +
                                    ": header needs a label cell and at least one slope edge");
      }
      for (std::size_t i = 1; i < cells.size(); ++i) {
        slope_edges.push_back(parseNumber(cells[i], line_no));
      }
      have_header = true;
      continue;
    }
    if (cells.size() != slope_edges.size() + 1) {
      std::ostringstream msg;
      msg << "line " << line_no << ": expected " << slope_edges.size() + 1 << " cells, found "
          << cells.size();
      throw std::invalid_argument(msg.str());
    }
    roughness_edges.push_back(parseNumber(cells[0], line_no));
    std::vector<double> row;
    for (std::size_t i = 1; i < cells.size(); ++i) row.push_back(parseNumber(cells[i], line_no));
    rows.push_back(std::move(row));
  }
  if (!have_header) throw std::invalid_argument("no header line (roughness\\slope,edges...)");
  if (rows.empty()) throw std::invalid_argument("no roughness rows after the header");
  Eigen::MatrixXd values(static_cast<Eigen::Index>(rows.size()),
                         static_cast<Eigen::Index>(slope_edges.size()));
  for (std::size_t r = 0; r < rows.size(); ++r) {
    for (std::size_t c = 0; c < rows[r].size(); ++c) {
      values(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = rows[r][c];
    }
  }
  return RuleTable(std::move(slope_edges), std::move(roughness_edges), std::move(values));
}

std::string RuleTable::toCsv() const {
  std::ostringstream out;
  out << std::setprecision(17);
  out << "# mobmap rule table: rows are roughness bins, columns slope bins (degrees).\n"
      << "# Each number is a bin's lower edge; the last bin on each axis is open ended.\n";
  out << "roughness\\slope";
  for (double e : slope_edges_deg_) out << ',' << e;
  out << '\n';
  for (std::size_t r = 0; r < roughness_edges_.size(); ++r) {
    out << roughness_edges_[r];
    for (Eigen::Index c = 0; c < values_.cols(); ++c) {
      out << ',' << values_(static_cast<Eigen::Index>(r), c);
    }
    out << '\n';
  }
  return out.str();
}

int RuleTable::slopeBin(double slope_deg) const {
  checkInput(slope_deg, "slope");
  return binOf(slope_edges_deg_, slope_deg);
}

int RuleTable::roughnessBin(double roughness) const {
  checkInput(roughness, "roughness");
  return binOf(roughness_edges_, roughness);
}

double RuleTable::lookup(double slope_deg, double roughness) const {
  return values_(roughnessBin(roughness), slopeBin(slope_deg));
}

bool RuleTable::operator==(const RuleTable& other) const {
  return slope_edges_deg_ == other.slope_edges_deg_ &&
         roughness_edges_ == other.roughness_edges_ && values_ == other.values_;
}

}  // namespace mobmap::gp
