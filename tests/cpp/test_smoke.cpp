// Proves the test plumbing: GoogleTest, VTK's readers, the working directory
// and $MATRIXTREE_DATA. Uses nothing from the engine.
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include <vtkNew.h>
#include <vtkPLYReader.h>
#include <vtkPolyData.h>

namespace
{
std::filesystem::path dataDir()
{
  const char* env = std::getenv("MATRIXTREE_DATA");
  return env ? std::filesystem::path(env) : std::filesystem::path("../shared/data");
}
} // namespace

TEST(Smoke, DataDirectoryIsSet)
{
  const char* env = std::getenv("MATRIXTREE_DATA");
  ASSERT_NE(env, nullptr) << "ctest must set MATRIXTREE_DATA";
  EXPECT_TRUE(std::filesystem::is_directory(env)) << env;
}

TEST(Smoke, RunsFromProjectRoot)
{
  EXPECT_TRUE(std::filesystem::exists("CMakeLists.txt"));
  EXPECT_TRUE(std::filesystem::is_directory("engine"));
}

TEST(Smoke, PlyReaderReadsBunny)
{
  const std::filesystem::path file = dataDir() / "meshes" / "bunny.ply";
  ASSERT_TRUE(std::filesystem::exists(file)) << file;

  vtkNew<vtkPLYReader> reader;
  reader->SetFileName(file.string().c_str());
  reader->Update();
  vtkPolyData* mesh = reader->GetOutput();
  ASSERT_NE(mesh, nullptr);
  EXPECT_EQ(mesh->GetNumberOfPolys(), 69451);
  EXPECT_GT(mesh->GetNumberOfPoints(), 0);
}
