// The only C++ in smplpix: Ceres Solver and nanoflann behind the extern "C" API of
// ceres_bridge.h. Every entry point catches everything: no C++ exception reaches C.
#include "fit/ceres_bridge.h"

#include <ceres/ceres.h>
#include <glog/logging.h>
#include <nanoflann.hpp>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <string>
#include <thread>
#include <vector>

namespace {

thread_local std::string g_last_error;

void set_error(const char *what, const char *detail) {
  g_last_error = std::string(what) + (detail && *detail ? std::string(": ") + detail : std::string());
}

// f() with every exception caught: its message becomes the last error (what: the entry point)
// and `fail` is returned instead.
template <class R, class F>
R guarded(const char *what, R fail, F &&f) {
  try {
    return f();
  } catch (const std::exception &e) {
    set_error(what, e.what());
  } catch (...) {
    set_error(what, "unknown exception");
  }
  return fail;
}

// A residual block whose values and Jacobians come from a C callback.
class CCost final : public ceres::CostFunction {
 public:
  CCost(spx_ceres_cost_fn fn, void *user, int nres, const std::vector<int> &sizes) : fn_(fn), user_(user) {
    set_num_residuals(nres);
    for (int s : sizes) mutable_parameter_block_sizes()->push_back(s);
  }
  bool Evaluate(double const *const *parameters, double *residuals, double **jacobians) const override {
    return fn_(user_, parameters, residuals, jacobians) != 0;
  }

 private:
  spx_ceres_cost_fn fn_;
  void *user_;
};

// Shared precomputation before each evaluation (posed vertices and their Jacobians).
class CPrepare final : public ceres::EvaluationCallback {
 public:
  CPrepare(spx_ceres_prepare_fn fn, void *user) : fn_(fn), user_(user) {}
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override {
    if (fn_ && !fn_(user_, evaluate_jacobians ? 1 : 0, new_evaluation_point ? 1 : 0)) failed = true;
  }
  bool failed = false;

 private:
  spx_ceres_prepare_fn fn_;
  void *user_;
};

struct Cloud {
  std::vector<float> p;
  size_t kdtree_get_point_count() const { return p.size() / 3; }
  float kdtree_get_pt(size_t i, size_t d) const { return p[i * 3 + d]; }
  template <class B>
  bool kdtree_get_bbox(B &) const {
    return false;
  }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Cloud>, Cloud, 3, uint32_t>;

}  // namespace

struct spx_ceres_problem {
  std::unique_ptr<CPrepare> prepare;
  std::unique_ptr<ceres::Problem> problem;
};

struct spx_kdtree {
  Cloud cloud;
  std::unique_ptr<Tree> tree;
};

extern "C" {

const char *spx_ceres_last_error(void) { return g_last_error.c_str(); }

void spx_ceres_options_default(spx_ceres_options *o) {
  if (!o) return;
  o->linear_solver = SPX_LS_DENSE_NORMAL_CHOLESKY;
  o->threads = 1;
  o->max_iterations = 50;
  o->function_tolerance = 0;
  o->gradient_tolerance = 0;
  o->parameter_tolerance = 0;
  o->progress = 0;
}

spx_ceres_problem *spx_ceres_problem_create(spx_ceres_prepare_fn prepare, void *prepare_user) {
  return guarded<spx_ceres_problem *>("ceres problem", nullptr, [&] {
    std::unique_ptr<spx_ceres_problem> p(new spx_ceres_problem);
    ceres::Problem::Options po;
    if (prepare) {
      p->prepare.reset(new CPrepare(prepare, prepare_user));
      po.evaluation_callback = p->prepare.get();
    }
    p->problem.reset(new ceres::Problem(po));
    return p.release();
  });
}

void spx_ceres_problem_destroy(spx_ceres_problem *p) {
  try {
    if (p) {
      p->problem.reset();  // the problem refers to the callback: destroy it first
      delete p;
    }
  } catch (...) {
  }
}

int spx_ceres_add_block(spx_ceres_problem *p, double *x, int size) {
  if (!p || !x || size <= 0) return set_error("ceres add block", "bad argument"), -1;
  return guarded("ceres add block", -1, [&] {
    p->problem->AddParameterBlock(x, size);
    return 0;
  });
}

int spx_ceres_set_constant(spx_ceres_problem *p, double *x, int constant) {
  if (!p || !x || !p->problem->HasParameterBlock(x)) return set_error("ceres set constant", "unknown block"), -1;
  return guarded("ceres set constant", -1, [&] {
    if (constant) p->problem->SetParameterBlockConstant(x);
    else p->problem->SetParameterBlockVariable(x);
    return 0;
  });
}

int spx_ceres_add_residual(spx_ceres_problem *p, spx_ceres_cost_fn fn, void *user, int num_residuals, int nblocks,
                           const int *block_sizes, double *const *blocks, int loss, double loss_scale) {
  if (!p || !fn || num_residuals <= 0 || nblocks <= 0 || !block_sizes || !blocks)
    return set_error("ceres add residual", "bad argument"), -1;
  if (loss != SPX_LOSS_NONE && !(loss_scale > 0)) return set_error("ceres add residual", "loss scale must be > 0"), -1;
  return guarded("ceres add residual", -1, [&] {
    std::vector<int> sizes(block_sizes, block_sizes + nblocks);
    std::vector<double *> ptrs(blocks, blocks + nblocks);
    for (int i = 0; i < nblocks; i++)
      if (!ptrs[i] || sizes[i] <= 0) return set_error("ceres add residual", "bad block"), -1;
    ceres::LossFunction *lf = nullptr;
    if (loss == SPX_LOSS_HUBER) lf = new ceres::HuberLoss(loss_scale);
    else if (loss == SPX_LOSS_CAUCHY) lf = new ceres::CauchyLoss(loss_scale);
    p->problem->AddResidualBlock(new CCost(fn, user, num_residuals, sizes), lf, ptrs);
    return 0;
  });
}

int spx_ceres_num_residual_blocks(const spx_ceres_problem *p) { return p ? p->problem->NumResidualBlocks() : 0; }

int spx_ceres_solve(spx_ceres_problem *p, const spx_ceres_options *o, spx_ceres_summary *s) {
  if (!p || !o || !s) return set_error("ceres solve", "bad argument"), -1;
  std::memset(s, 0, sizeof *s);
  return guarded("ceres solve", -1, [&] {
    ceres::Solver::Options so;
    switch (o->linear_solver) {
      case SPX_LS_DENSE_QR: so.linear_solver_type = ceres::DENSE_QR; break;
      case SPX_LS_SPARSE_NORMAL_CHOLESKY: so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY; break;
      case SPX_LS_CGNR: so.linear_solver_type = ceres::CGNR; break;
      case SPX_LS_ITERATIVE_SCHUR: so.linear_solver_type = ceres::ITERATIVE_SCHUR; break;
      default: so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY; break;
    }
    so.num_threads = std::max(1, o->threads);
    so.max_num_iterations = std::max(0, o->max_iterations);
    if (o->function_tolerance > 0) so.function_tolerance = o->function_tolerance;
    if (o->gradient_tolerance > 0) so.gradient_tolerance = o->gradient_tolerance;
    if (o->parameter_tolerance > 0) so.parameter_tolerance = o->parameter_tolerance;
    so.minimizer_progress_to_stdout = o->progress != 0;
    so.logging_type = o->progress ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
    std::string why;
    if (!so.IsValid(&why)) return set_error("ceres solver options", why.c_str()), -1;
    if (p->prepare) p->prepare->failed = false;
    ceres::Solver::Summary sum;
    {
      // logging off: Ceres reports failures through glog (LOG(ERROR)); the summary carries them
      // here instead. The host's level is restored afterwards.
      struct Quiet {
        int saved = FLAGS_minloglevel;
        Quiet() { FLAGS_minloglevel = std::max(saved, (int)google::GLOG_FATAL); }
        ~Quiet() { FLAGS_minloglevel = saved; }
      } quiet;
      ceres::Solve(so, p->problem.get(), &sum);
    }
    s->initial_cost = sum.initial_cost;
    s->final_cost = sum.final_cost;
    // Ceres lists iteration 0 (the initial evaluation) too
    s->iterations = sum.iterations.empty() ? 0 : (int32_t)sum.iterations.size() - 1;
    s->time_s = sum.total_time_in_seconds;
    switch (sum.termination_type) {
      case ceres::CONVERGENCE: s->termination = SPX_TERM_CONVERGENCE; break;
      case ceres::NO_CONVERGENCE: s->termination = SPX_TERM_NO_CONVERGENCE; break;
      case ceres::USER_SUCCESS:
      case ceres::USER_FAILURE: s->termination = SPX_TERM_USER; break;
      default: s->termination = SPX_TERM_FAILURE; break;
    }
    std::snprintf(s->message, sizeof s->message, "%s", sum.message.c_str());
    if (p->prepare && p->prepare->failed) return set_error("ceres solve", "evaluation callback failed"), -1;
    if (sum.termination_type == ceres::FAILURE) return set_error("ceres solve", sum.message.c_str()), -1;
    return 0;
  });
}

spx_kdtree *spx_kdtree_build(const float *pts, int32_t n) {
  if (!pts || n <= 0) return set_error("kd-tree", "no points"), nullptr;
  return guarded<spx_kdtree *>("kd-tree build", nullptr, [&] {
    std::unique_ptr<spx_kdtree> t(new spx_kdtree);
    t->cloud.p.assign(pts, pts + (size_t)n * 3);
    t->tree.reset(new Tree(3, t->cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16)));
    return t.release();
  });
}

void spx_kdtree_free(spx_kdtree *t) { delete t; }

int spx_kdtree_query(const spx_kdtree *t, const float *q, int32_t nq, int k, int32_t *idx, float *d2, int threads) {
  if (!t || (!q && nq > 0) || nq < 0 || k < 1 || !idx) return set_error("kd-tree query", "bad argument"), -1;
  size_t npts = t->cloud.kdtree_get_point_count();
  if ((size_t)k > npts) return set_error("kd-tree query", "k larger than the point count"), -1;
  return guarded("kd-tree query", -1, [&] {
    auto work = [&](int32_t a, int32_t b) {
      std::vector<uint32_t> ii((size_t)k);
      std::vector<float> dd((size_t)k);
      for (int32_t i = a; i < b; i++) {
        size_t got = t->tree->knnSearch(q + (size_t)i * 3, (size_t)k, ii.data(), dd.data());
        for (int j = 0; j < k; j++) {
          size_t jj = (size_t)j < got ? (size_t)j : (got ? got - 1 : 0);
          idx[(size_t)i * k + j] = (int32_t)ii[jj];
          if (d2) d2[(size_t)i * k + j] = dd[jj];
        }
      }
    };
    int nt = std::max(1, std::min(threads, 64));
    if (nt == 1 || nq < 4096) {
      work(0, nq);
    } else {
      std::vector<std::thread> th;
      int32_t chunk = (nq + nt - 1) / nt;
      for (int i = 0; i < nt; i++) {
        int32_t a = i * chunk, b = std::min(nq, a + chunk);
        if (a < b) th.emplace_back(work, a, b);
      }
      for (auto &x : th) x.join();
    }
    return 0;
  });
}

}  // extern "C"
