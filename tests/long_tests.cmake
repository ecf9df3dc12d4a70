# Read by ctest after the discovered tests (TEST_INCLUDE_FILES, tests/CMakeLists.txt). The
# longest tests of the sanitized builds, where each takes 15 s to 100 s (tens of times
# their release time): ctest starts a test of higher COST first, and these, started first,
# run beside the many short ones. A fresh build has no timings of its own and would start
# them in the order they were declared, the last of them at the end beside nothing. ctest
# ignores a name it does not know: keep the names current when a test is renamed.
foreach(test IN ITEMS
    physics_tests.ElasticGas.ContinuousModeConservesEnergyAndHoldsEveryone
    extremes_tests.RandomScenes.BoxedSpheresUnderGravityStayFiniteAndInside
    server_tests.DefaultScene.NeverSettlesAndKeepsItsEnergy
    physics_tests.TreeGravity.MomentumDriftOverARunIsSmallAndMeasured
    physics_tests.DiscreteThreads.FarFlungSphereStaysDeterministic
    physics_tests.Broadphases.GiveTheSameSimulationBitForBit
    physics_tests.DiscreteThreads.AnyNumberOfThreadsGivesTheSameBits
    physics_tests.SortedBodies.LargeWorldsKeepTheirBodiesInCellOrderAndTheirResults
    server_tests.HeadlessRun.GalaxyRunsWithTheTreeAndKeepsEnergy
    extremes_tests.StepSize.AMillionSecondStepIsFiniteAndKeepsSpheresInTheBox
    extremes_tests.StepSize.AMillionSecondStepOfAnOrbitIsFiniteOrRefused
    server_tests.Interest.TheCompactStreamIsTheFullFormFilteredByTheSameInterestThroughChurn
    physics_tests.ContinuousThreads.AnyNumberOfThreadsGivesTheSameBits
    physics_tests.MinimumBoundingSphere.MillionPointsWithKnownAnswer
    server_tests.HostileInput.EachIsAnsweredAsDocumentedAndChangesNothing)
  set_tests_properties(${test} PROPERTIES COST 100)
endforeach()
