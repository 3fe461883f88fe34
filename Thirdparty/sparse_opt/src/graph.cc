#include "sparse_opt/graph.h"

#include <cxxabi.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <typeinfo>

#include "solver.h"

namespace sparse_opt {

namespace {
std::string demangle(const char* name) {
  int status = 0;
  char* text = abi::__cxa_demangle(name, nullptr, nullptr, &status);
  if (status != 0 || text == nullptr) return name;
  std::string result(text);
  std::free(text);
  return result;
}
}  // namespace

std::string VertexBase::typeName() const { return demangle(typeid(*this).name()); }
std::string EdgeBase::typeName() const { return demangle(typeid(*this).name()); }

void EdgeBase::setVertex(int i, VertexBase* v) {
  if (i < 0 || i >= numVertices()) {
    throw Error("sparse_opt: " + typeName() + "::setVertex: slot " + std::to_string(i) + " out of range [0, " +
                std::to_string(numVertices()) + ")");
  }
  if (v != nullptr && !acceptsVertex(i, v)) {
    throw Error("sparse_opt: " + typeName() + "::setVertex: slot " + std::to_string(i) + " cannot take vertex " +
                std::to_string(v->id()) + " of type " + v->typeName() + " (dimension " +
                std::to_string(v->dimension()) + ")");
  }
  vertices_[static_cast<size_t>(i)] = v;
}

double EdgeBase::robustChi2() const { return cost_scale_ * (kernel_ ? kernel_->evaluate(chi2_)[0] : chi2_); }

void EdgeBase::setCostScale(double scale) {
  if (!(scale >= 0.0) || !std::isfinite(scale)) {
    throw Error("sparse_opt: " + typeName() + "::setCostScale: scale " + std::to_string(scale) +
                ", expected a finite value >= 0");
  }
  cost_scale_ = scale;
}

double EdgeBase::evaluateChi2() {
  computeError();
  chi2_ = squaredError();
  return robustChi2();
}

Graph::Graph() : solver_(std::make_unique<internal::Solver>()) {}
Graph::~Graph() = default;

void Graph::addVertexImpl(std::unique_ptr<VertexBase> vertex) {
  if (!vertex) throw Error("sparse_opt: Graph::addVertex: null vertex");
  const int id = vertex->id();
  if (vertices_.count(id) != 0) {
    throw Error("sparse_opt: Graph::addVertex: vertex id " + std::to_string(id) + " already in the graph");
  }
  vertices_.emplace(id, std::move(vertex));
  ++version_;
}

void Graph::addEdgeImpl(std::unique_ptr<EdgeBase> edge) {
  if (!edge) throw Error("sparse_opt: Graph::addEdge: null edge");
  // Built on the error path only: demangling the type name per edge costs more than adding it.
  const auto what = [&edge] { return "sparse_opt: Graph::addEdge: edge of type " + edge->typeName(); };
  for (int s = 0; s < edge->numVertices(); ++s) {
    const VertexBase* v = edge->vertex(s);
    if (v == nullptr) throw Error(what() + ": vertex slot " + std::to_string(s) + " is not set");
    const auto it = vertices_.find(v->id());
    if (it == vertices_.end() || it->second.get() != v) {
      throw Error(what() + ": vertex " + std::to_string(v->id()) + " (slot " + std::to_string(s) +
                  ") is not in the graph");
    }
    for (int t = 0; t < s; ++t) {
      if (edge->vertex(t) == v) {
        throw Error(what() + ": vertex " + std::to_string(v->id()) + " appears in slots " + std::to_string(t) +
                    " and " + std::to_string(s));
      }
    }
  }
  edge->id_ = next_edge_id_++;
  edges_.push_back(std::move(edge));
  ++version_;
}

void Graph::removeEdge(const EdgeBase* edge) {
  if (edge == nullptr) return;
  const auto it = std::lower_bound(edges_.begin(), edges_.end(), edge->id(),
                                   [](const std::unique_ptr<EdgeBase>& e, int id) { return e->id() < id; });
  if (it != edges_.end() && it->get() == edge) {
    edges_.erase(it);
    ++version_;
  }
}

void Graph::removeVertex(int vertex_id) {
  const auto it = vertices_.find(vertex_id);
  if (it == vertices_.end()) return;
  const VertexBase* v = it->second.get();
  edges_.erase(std::remove_if(edges_.begin(), edges_.end(),
                              [v](const std::unique_ptr<EdgeBase>& e) {
                                bool uses = false;
                                for (int s = 0; s < e->numVertices(); ++s) uses = uses || e->vertex(s) == v;
                                return uses;
                              }),
               edges_.end());
  vertices_.erase(it);
  ++version_;
}

VertexBase* Graph::vertex(int vertex_id) const {
  const auto it = vertices_.find(vertex_id);
  return it == vertices_.end() ? nullptr : it->second.get();
}

std::vector<EdgeBase*> Graph::edges() const {
  std::vector<EdgeBase*> result;
  result.reserve(edges_.size());
  for (const auto& e : edges_) result.push_back(e.get());
  return result;
}

std::vector<EdgeBase*> Graph::activeEdges(int level) const {
  std::vector<EdgeBase*> result;
  result.reserve(edges_.size());
  for (const auto& e : edges_) {
    if (e->level() == level) result.push_back(e.get());
  }
  return result;
}

Summary Graph::optimize(const Options& options) {
  if (options.num_threads < 1) throw Error("sparse_opt: Options::num_threads must be >= 1");
  if (options.max_iterations < 0) throw Error("sparse_opt: Options::max_iterations must be >= 0");
  const auto setup_start = std::chrono::steady_clock::now();
  solver_->setup(activeEdges(options.level), options.use_schur, version_);
  solver_->setSetupTime(std::chrono::duration<double>(std::chrono::steady_clock::now() - setup_start).count());
  Summary summary = solver_->run(options);
  // Edges of other levels get their chi2() at the final estimate too (outlier re-checks).
  for (const auto& e : edges_) {
    if (e->level() != options.level) e->evaluateChi2();
  }
  return summary;
}

double Graph::chi2(int level) {
  double sum = 0.0;
  for (const auto& e : edges_) {
    if (e->level() == level) sum += e->evaluateChi2();
  }
  return sum;
}

std::vector<Eigen::MatrixXd> Graph::marginalCovariance(const std::vector<int>& vertex_ids, const Options& options) {
  std::vector<const VertexBase*> selected;
  bool any_marginalized = false;
  for (int id : vertex_ids) {
    const VertexBase* v = vertex(id);
    if (v == nullptr) throw Error("sparse_opt: marginalCovariance: vertex " + std::to_string(id) + " is not in the graph");
    any_marginalized = any_marginalized || v->marginalized();
    selected.push_back(v);
  }
  solver_->setup(activeEdges(options.level), options.use_schur && !any_marginalized, version_);
  return solver_->covariance(selected, options);
}

}  // namespace sparse_opt
