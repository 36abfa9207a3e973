#include "ComponentSplit.hpp"

#include <string>
#include <utility>

#include "SolverUtil.hpp"

namespace mmval::simulate::detail {

namespace {

/// One rank's component: its rows of the block (global indices of the block's numbering), the
/// serial matrix of those rows and columns, the scatter between the block's vector and the
/// serial one, and the serial KSP (preonly + BoomerAMG unless the options say otherwise).
struct Component {
  std::vector<char> is_u;  ///< this rank's block rows: u (1) or v (0), in order
  std::string prefix;      ///< the serial KSP's options prefix
  IS is = nullptr;
  Mat* sub = nullptr;
  VecScatter scatter = nullptr;
  Vec xs = nullptr, ys = nullptr;
  KSP inner = nullptr;

  void release() {
    if (inner != nullptr) KSPDestroy(&inner);
    if (scatter != nullptr) VecScatterDestroy(&scatter);
    if (xs != nullptr) VecDestroy(&xs);
    if (ys != nullptr) VecDestroy(&ys);
    if (sub != nullptr) MatDestroySubMatrices(1, &sub);
    if (is != nullptr) ISDestroy(&is);
  }
};

/// The global block rows of component `comp` (0: u, 1: v) gathered on rank `comp`, ascending
/// (each rank's rows are ascending and ranks hold ascending ranges). Other ranks: empty.
PetscErrorCode gatherComponent(MPI_Comm comm, const std::vector<PetscInt>& mine, int comp, std::vector<PetscInt>& out) {
  int rank = 0, size = 1;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscCallMPI(MPI_Comm_size(comm, &size));
  const int n = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<std::size_t>(size)), starts(static_cast<std::size_t>(size), 0);
  PetscCallMPI(MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comp, comm));
  if (rank == comp) {
    for (int r = 1; r < size; ++r) starts[static_cast<std::size_t>(r)] = starts[static_cast<std::size_t>(r) - 1] + counts[static_cast<std::size_t>(r) - 1];
    out.resize(static_cast<std::size_t>(starts.back() + counts.back()));
  }
  PetscCallMPI(MPI_Gatherv(mine.data(), n, MPIU_INT, out.data(), counts.data(), starts.data(), MPIU_INT, comp, comm));
  return 0;
}

PetscErrorCode setUpComponent(PC pc) {
  PetscFunctionBeginUser;
  Component* c = nullptr;
  PetscCall(PCShellGetContext(pc, &c));
  c->release();
  Mat P = nullptr;
  PetscCall(PCGetOperators(pc, nullptr, &P));
  MPI_Comm comm = PetscObjectComm(reinterpret_cast<PetscObject>(P));
  int rank = 0;
  PetscCallMPI(MPI_Comm_rank(comm, &rank));
  PetscInt lo = 0, hi = 0;
  PetscCall(MatGetOwnershipRange(P, &lo, &hi));
  PetscCheck(static_cast<std::size_t>(hi - lo) == c->is_u.size(), comm, PETSC_ERR_PLIB, "velocity block rows %d, component flags %d",
             static_cast<int>(hi - lo), static_cast<int>(c->is_u.size()));
  std::vector<PetscInt> of[2], mine;
  for (PetscInt r = lo; r < hi; ++r) of[c->is_u[static_cast<std::size_t>(r - lo)] != 0 ? 0 : 1].push_back(r);
  for (int comp = 0; comp < 2; ++comp) PetscCall(gatherComponent(comm, of[comp], comp, mine));  // rank 0: u, rank 1: v
  PetscCall(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(mine.size()), mine.data(), PETSC_COPY_VALUES, &c->is));
  PetscCall(MatCreateSubMatrices(P, 1, &c->is, &c->is, MAT_INITIAL_MATRIX, &c->sub));
  PetscCall(VecCreateSeq(PETSC_COMM_SELF, static_cast<PetscInt>(mine.size()), &c->xs));
  PetscCall(VecDuplicate(c->xs, &c->ys));
  Vec block = nullptr;
  PetscCall(MatCreateVecs(P, &block, nullptr));
  PetscCall(VecScatterCreate(block, c->is, c->xs, nullptr, &c->scatter));
  PetscCall(VecDestroy(&block));
  PetscCall(KSPCreate(PETSC_COMM_SELF, &c->inner));
  PetscCall(KSPSetOptionsPrefix(c->inner, c->prefix.c_str()));
  PetscCall(KSPSetType(c->inner, KSPPREONLY));
  PC ipc = nullptr;
  PetscCall(KSPGetPC(c->inner, &ipc));
  PetscCall(PCSetType(ipc, PCHYPRE));
  PetscCall(KSPSetOperators(c->inner, c->sub[0], c->sub[0]));
  PetscCall(KSPSetFromOptions(c->inner));
  PetscCall(KSPSetUp(c->inner));
  PetscFunctionReturn(0);
}

PetscErrorCode applyComponent(PC pc, Vec x, Vec y) {
  PetscFunctionBeginUser;
  Component* c = nullptr;
  PetscCall(PCShellGetContext(pc, &c));
  PetscCall(VecScatterBegin(c->scatter, x, c->xs, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(VecScatterEnd(c->scatter, x, c->xs, INSERT_VALUES, SCATTER_FORWARD));
  PetscCall(KSPSolve(c->inner, c->xs, c->ys));
  // The two ranks' rows partition the block, so every entry of y is written once.
  PetscCall(VecScatterBegin(c->scatter, c->ys, y, INSERT_VALUES, SCATTER_REVERSE));
  PetscCall(VecScatterEnd(c->scatter, c->ys, y, INSERT_VALUES, SCATTER_REVERSE));
  PetscFunctionReturn(0);
}

PetscErrorCode destroyComponent(PC pc) {
  PetscFunctionBeginUser;
  Component* c = nullptr;
  PetscCall(PCShellGetContext(pc, &c));
  if (c != nullptr) c->release();
  delete c;
  PetscFunctionReturn(0);
}

}  // namespace

bool componentSplitWanted(MPI_Comm comm, const char* prefix, const std::string& user_pc) {
  int size = 1;
  MPI_Comm_size(comm, &size);
  if (size != 2) return false;
  PetscBool on = PETSC_TRUE, set = PETSC_FALSE;
  const std::string key = "-" + std::string(prefix) + "fieldsplit_0_by_component";
  PetscOptionsGetBool(nullptr, nullptr, key.c_str(), &on, &set);
  if (set == PETSC_TRUE) return on == PETSC_TRUE;
  return user_pc.empty();
}

std::string userVelocityPcType(const char* prefix) {
  char value[256] = {0};
  PetscBool set = PETSC_FALSE;
  const std::string key = "-" + std::string(prefix) + "fieldsplit_0_pc_type";
  PetscOptionsGetString(nullptr, nullptr, key.c_str(), value, sizeof value, &set);
  // The solver itself puts its default there (CoupledSystem::createKsp): only another value is a choice.
  return set == PETSC_TRUE && std::string(value) != kVelocityBlockPcDefault ? std::string(value) : std::string();
}

PC velocityBlockToSplit(KSP k) {
  PC pc = nullptr;
  check(KSPGetPC(k, &pc), "KSPGetPC");
  KSP* subs = nullptr;
  PetscInt n = 0;
  check(PCFieldSplitGetSubKSP(pc, &n, &subs), "PCFieldSplitGetSubKSP");
  KSP vel = n > 0 ? subs[0] : nullptr;
  PetscFree(subs);
  if (vel == nullptr) throw std::runtime_error("PETSc error in velocityBlockToSplit: the fieldsplit has no velocity block");
  PC vpc = nullptr;
  check(KSPGetPC(vel, &vpc), "KSPGetPC");
  PetscBool shell = PETSC_FALSE;
  check(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(vpc), PCSHELL, &shell), "type");
  return shell == PETSC_TRUE ? nullptr : vpc;
}

void installComponentSplit(PC vpc, std::vector<char> is_u) {
  const char* prefix = nullptr;
  check(PCGetOptionsPrefix(vpc, &prefix), "prefix");
  auto* c = new Component;
  c->is_u = std::move(is_u);
  c->prefix = std::string(prefix != nullptr ? prefix : "") + "comp_";
  check(PCSetType(vpc, PCSHELL), "PCSetType shell");
  check(PCShellSetContext(vpc, c), "shell context");
  check(PCShellSetDestroy(vpc, destroyComponent), "shell destroy");
  check(PCShellSetSetUp(vpc, setUpComponent), "shell setup");
  check(PCShellSetApply(vpc, applyComponent), "shell apply");
  check(PCShellSetName(vpc, "velocity block by component: rank 0 u, rank 1 v, serial BoomerAMG each"), "shell name");
}

}  // namespace mmval::simulate::detail
