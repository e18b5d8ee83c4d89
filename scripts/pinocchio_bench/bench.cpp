// Per-call timing of Pinocchio's dynamics on the Franka Panda (7 arm joints),
// a same-machine anchor for the generated Rust functions of benches/dynamics.rs.
//
// Usage: bench PANDA_URDF [REPETITIONS [PASSES_PER_REPETITION]]
//
// The model is example-robot-data's panda_description URDF with a fixed base;
// the two prismatic finger joints are locked at 0 by buildReducedModel, which
// leaves joints 1..7 of the arm (the hand's mass merged into link 7).
//
// States: the 4,096 states of benches/dynamics.rs (same generator, same
// seed): q in +-pi, qd in +-3 rad/s, qdd in +-10 rad/s^2, tau in +-20 N m.
//
// Timing: one pass calls the function once on every state; a repetition is
// PASSES passes; after a warm-up, the best and the median of REPETITIONS
// repetitions are reported, divided by the number of calls (ns per call).
// Every call feeds one entry of its result into a sum written to a volatile,
// so no call can be dropped.

#include <pinocchio/parsers/urdf.hpp>

#include <pinocchio/algorithm/aba-derivatives.hpp>
#include <pinocchio/algorithm/aba.hpp>
#include <pinocchio/algorithm/crba.hpp>
#include <pinocchio/algorithm/frames.hpp>
#include <pinocchio/algorithm/jacobian.hpp>
#include <pinocchio/algorithm/joint-configuration.hpp>
#include <pinocchio/algorithm/model.hpp>
#include <pinocchio/algorithm/rnea-derivatives.hpp>
#include <pinocchio/algorithm/rnea.hpp>
#include <pinocchio/multibody.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace pin = pinocchio;

namespace
{
  constexpr int kStates = 4096;
  constexpr int kDof = 7;

  volatile double g_sink = 0.0;

  struct State
  {
    Eigen::VectorXd q, qd, qdd, tau;
  };

  // The generator of benches/dynamics.rs `panda_states`: a 64-bit LCG from
  // seed 5, each draw scale * (53-bit fraction in [0, 2) - 1).
  std::vector<State> make_states()
  {
    std::uint64_t seed = 5;
    auto draw = [&seed](double scale) {
      Eigen::VectorXd v(kDof);
      for (int i = 0; i < kDof; ++i)
      {
        seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
        v[i] = scale * (double(seed >> 11) / double(std::uint64_t(1) << 52) - 1.0);
      }
      return v;
    };
    std::vector<State> states;
    states.reserve(kStates);
    for (int k = 0; k < kStates; ++k)
    {
      State s;
      s.q = draw(M_PI);
      s.qd = draw(3.0);
      s.qdd = draw(10.0);
      s.tau = draw(20.0);
      states.push_back(std::move(s));
    }
    return states;
  }

  struct Timing
  {
    double best_ns, median_ns;
  };

  // `call(state)` returns one number taken from its result.
  template<typename Call>
  Timing time_per_call(const std::vector<State> & states, int repetitions, int passes, Call call)
  {
    using Clock = std::chrono::steady_clock;
    double acc = 0.0;
    for (int w = 0; w < 2 * passes; ++w) // warm-up
      for (const State & s : states)
        acc += call(s);
    std::vector<double> per_call;
    per_call.reserve(repetitions);
    for (int r = 0; r < repetitions; ++r)
    {
      const auto t0 = Clock::now();
      for (int p = 0; p < passes; ++p)
        for (const State & s : states)
          acc += call(s);
      const auto t1 = Clock::now();
      const double ns = std::chrono::duration<double, std::nano>(t1 - t0).count();
      per_call.push_back(ns / (double(passes) * double(states.size())));
    }
    g_sink = g_sink + acc;
    std::sort(per_call.begin(), per_call.end());
    return {per_call.front(), per_call[per_call.size() / 2]};
  }
} // namespace

int main(int argc, char ** argv)
{
  if (argc < 2)
  {
    std::fprintf(stderr, "usage: %s PANDA_URDF [REPETITIONS [PASSES]]\n", argv[0]);
    return 2;
  }
  const std::string urdf = argv[1];
  const int repetitions = argc > 2 ? std::atoi(argv[2]) : 15;
  const int passes = argc > 3 ? std::atoi(argv[3]) : 5;
  if (repetitions < 1 || passes < 1)
  {
    std::fprintf(stderr, "REPETITIONS and PASSES must be positive\n");
    return 2;
  }

  // --- model: whole URDF, fixed base, fingers locked at 0 ---------------
  pin::Model full;
  pin::urdf::buildModel(urdf, full);
  std::vector<pin::JointIndex> locked;
  for (const char * name : {"panda_finger_joint1", "panda_finger_joint2"})
  {
    if (!full.existJointName(name))
    {
      std::fprintf(stderr, "joint %s not in %s\n", name, urdf.c_str());
      return 1;
    }
    locked.push_back(full.getJointId(name));
  }
  const Eigen::VectorXd q_lock = Eigen::VectorXd::Zero(full.nq);
  const pin::Model model = pin::buildReducedModel(full, locked, q_lock);
  if (model.nq != kDof || model.nv != kDof)
  {
    std::fprintf(stderr, "reduced model has nq=%d nv=%d, expected 7\n", model.nq, model.nv);
    return 1;
  }
  const std::string tip_name = "panda_link7";
  if (!model.existBodyName(tip_name))
  {
    std::fprintf(stderr, "frame %s not in the reduced model\n", tip_name.c_str());
    return 1;
  }
  const pin::FrameIndex tip = model.getBodyId(tip_name);
  pin::Data data(model);

  const std::vector<State> states = make_states();

  // --- sanity: aba inverts rnea; crba agrees with rnea ------------------
  {
    double worst_aba = 0.0, worst_m = 0.0;
    for (int k = 0; k < 64; ++k)
    {
      const State & s = states[k];
      const Eigen::VectorXd tau = pin::rnea(model, data, s.q, s.qd, s.qdd);
      const Eigen::VectorXd qdd = pin::aba(model, data, s.q, s.qd, tau);
      worst_aba = std::max(worst_aba, (qdd - s.qdd).cwiseAbs().maxCoeff());
      const Eigen::VectorXd nle = pin::rnea(model, data, s.q, s.qd, Eigen::VectorXd::Zero(kDof));
      pin::crba(model, data, s.q);
      Eigen::MatrixXd m = data.M;
      m.triangularView<Eigen::StrictlyLower>() = m.transpose();
      worst_m = std::max(worst_m, (m * s.qdd + nle - tau).cwiseAbs().maxCoeff());
    }
    std::printf(
      "model: %s, nq = %d, tip frame %s, %zu frames, gravity z = %.2f\n", model.name.c_str(),
      model.nq, tip_name.c_str(), model.frames.size(), model.gravity.linear()[2]);
    std::printf(
      "check: |aba(rnea(qdd)) - qdd|max = %.1e, |M qdd + nle - rnea|max = %.1e\n", worst_aba,
      worst_m);
  }

  // --- timings ----------------------------------------------------------
  std::printf(
    "states %d, best and median of %d repetitions of %d passes (ns per call)\n\n", kStates,
    repetitions, passes);
  std::printf("%-68s %9s %9s\n", "function", "best", "median");
  auto row = [](const char * name, Timing t) {
    std::printf("%-68s %9.0f %9.0f\n", name, t.best_ns, t.median_ns);
    std::fflush(stdout);
  };

  row("rnea", time_per_call(states, repetitions, passes, [&](const State & s) {
        pin::rnea(model, data, s.q, s.qd, s.qdd);
        return data.tau[kDof - 1];
      }));
  row(
    "crba (upper triangle, as Pinocchio fills it)",
    time_per_call(states, repetitions, passes, [&](const State & s) {
      pin::crba(model, data, s.q);
      return data.M(0, kDof - 1);
    }));
  row("aba", time_per_call(states, repetitions, passes, [&](const State & s) {
        pin::aba(model, data, s.q, s.qd, s.tau);
        return data.ddq[kDof - 1];
      }));
  row(
    "computeRNEADerivatives", time_per_call(states, repetitions, passes, [&](const State & s) {
      pin::computeRNEADerivatives(model, data, s.q, s.qd, s.qdd);
      return data.dtau_dq(kDof - 1, 0) + data.dtau_dv(0, kDof - 1);
    }));
  row(
    "computeABADerivatives", time_per_call(states, repetitions, passes, [&](const State & s) {
      pin::computeABADerivatives(model, data, s.q, s.qd, s.tau);
      return data.ddq_dq(kDof - 1, 0) + data.ddq_dv(0, kDof - 1);
    }));

  // Tip pose + LOCAL_WORLD_ALIGNED Jacobian, the cheapest way: one call of
  // computeFrameJacobian runs the kinematics over the tip's support only,
  // sets data.oMf[tip] and fills J.
  pin::Data::Matrix6x J = pin::Data::Matrix6x::Zero(6, model.nv);
  row(
    "tip pose + Jacobian: computeFrameJacobian(LWA)",
    time_per_call(states, repetitions, passes, [&](const State & s) {
      pin::computeFrameJacobian(model, data, s.q, tip, pin::LOCAL_WORLD_ALIGNED, J);
      return data.oMf[tip].translation()[0] + J(0, kDof - 1);
    }));
  // The same result through the whole-model path, for comparison.
  row(
    "  (computeJointJacobians + updateFramePlacement + getFrameJacobian)",
    time_per_call(states, repetitions, passes, [&](const State & s) {
      pin::computeJointJacobians(model, data, s.q);
      pin::updateFramePlacement(model, data, tip);
      pin::getFrameJacobian(model, data, tip, pin::LOCAL_WORLD_ALIGNED, J);
      return data.oMf[tip].translation()[0] + J(0, kDof - 1);
    }));

  std::printf("\n(sink %.3e)\n", double(g_sink));
  return 0;
}
