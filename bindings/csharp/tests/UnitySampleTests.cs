// The Unity sample (unity/Samples~/AnimatorPartner/TroupePartner.cs) on the engine's clock,
// without the editor: compiled with the binding and UnityStub.cs, it runs the demo model at 20,
// 60 and 144 engine frames a second (each frame's length jittered by up to a quarter), 60 s each,
// with an actor Animator playing the CMU clip. Checked: the poses held stay bounded, the
// playhead keeps pace with the actor (it ends within one token of where it was behind once the
// first poses arrived), and the partner is shown (its spheres move).
//
//   LD_LIBRARY_PATH=target/debug mono unity-sample-tests.exe BUNDLES_DIR CLIP.npy
using System;
using System.Collections.Generic;
using System.IO;
using System.Reflection;
using System.Text;
using Troupe;
using Troupe.Samples;
using UnityEngine;

static class UnitySampleTests
{
    private const int Token = 4;

    // t2m-22's joint index for each Humanoid bone the sample asks for.
    private static readonly Dictionary<HumanBodyBones, int> Joint = new Dictionary<HumanBodyBones, int>
    {
        { HumanBodyBones.Hips, 0 }, { HumanBodyBones.LeftUpperLeg, 1 }, { HumanBodyBones.RightUpperLeg, 2 },
        { HumanBodyBones.Spine, 3 }, { HumanBodyBones.LeftLowerLeg, 4 }, { HumanBodyBones.RightLowerLeg, 5 },
        { HumanBodyBones.Chest, 6 }, { HumanBodyBones.LeftFoot, 7 }, { HumanBodyBones.RightFoot, 8 },
        { HumanBodyBones.UpperChest, 9 }, { HumanBodyBones.LeftToes, 10 }, { HumanBodyBones.RightToes, 11 },
        { HumanBodyBones.Neck, 12 }, { HumanBodyBones.LeftShoulder, 13 }, { HumanBodyBones.RightShoulder, 14 },
        { HumanBodyBones.Head, 15 }, { HumanBodyBones.LeftUpperArm, 16 }, { HumanBodyBones.RightUpperArm, 17 },
        { HumanBodyBones.LeftLowerArm, 18 }, { HumanBodyBones.RightLowerArm, 19 }, { HumanBodyBones.LeftHand, 20 },
        { HumanBodyBones.RightHand, 21 },
    };

    private static void Expect<T>(Action action) where T : Exception
    {
        try { action(); }
        catch (T) { return; }
        throw new Exception("FAILED: expected " + typeof(T).Name);
    }

    private static void Call(object target, string method)
    {
        target.GetType().GetMethod(method, BindingFlags.Instance | BindingFlags.NonPublic).Invoke(target, null);
    }

    private static int Main(string[] args)
    {
        if (args.Length != 2)
        {
            Console.Error.WriteLine("usage: unity-sample-tests.exe BUNDLES_DIR CLIP.npy");
            return 2;
        }
        // PosePlayback's own contract: misuse refused, interpolation between two poses.
        var play = new PosePlayback(2, 30f);
        var two = new float[2];
        Expect<ArgumentNullException>(() => play.Push(null, 1));
        Expect<ArgumentException>(() => play.Push(new float[3], 2));
        Expect<ArgumentOutOfRangeException>(() => play.Sample(-1f, two));
        Expect<ArgumentOutOfRangeException>(() => play.Sample(float.NaN, two));
        Expect<ArgumentOutOfRangeException>(() => new PosePlayback(66, 0f));
        if (play.Sample(0.1f, two)) throw new Exception("FAILED: a pose before any was pushed");
        play.Push(new[] { 0f, 0f, 10f, 20f }, 2);
        play.Sample(0.5f / 30f, two);
        if (Math.Abs(two[0] - 5f) > 1e-4 || Math.Abs(two[1] - 10f) > 1e-4)
            throw new Exception("FAILED: half way between two poses gave " + two[0] + ", " + two[1]);
        play.Sample(1f, two);
        if (two[0] != 10f || play.Queued != 1) throw new Exception("FAILED: the last pose is held");

        Application.streamingAssetsPath = args[0];
        int[] shape;
        float[] clip = Npy.Read(args[1], out shape); // [T, 22, 3], metres, Z up, 120 fps
        int clipFrames = shape[0];
        bool failed = false;
        foreach (int fps in new[] { 20, 60, 144 })
        {
            var rng = new Random(fps);
            double now = 0;
            var bones = new Transform[22];
            for (int j = 0; j < 22; j++) bones[j] = new Transform();
            var animator = new Animator { bones = b => bones[Joint[b]] };
            var partner = new TroupePartner { actor = animator };
            Call(partner, "Start");
            int maxQueued = 0;
            double gapAtFirst = double.NaN;
            long fedAtFirst = 0;
            double playheadAtFirst = 0;
            var firstShown = new UnityEngine.Vector3();
            bool moved = false;
            var sphere = (Transform[])typeof(TroupePartner)
                .GetField("partner", BindingFlags.Instance | BindingFlags.NonPublic).GetValue(partner);
            while (now < 60.0)
            {
                // The actor where the clip is at this time (looped), in Unity's axes: Z up
                // right-handed to Y up left-handed is (x, z, y).
                int f = (int)(now * 120.0) % clipFrames;
                for (int j = 0; j < 22; j++)
                {
                    int at = (f * 22 + j) * 3;
                    bones[j].position = new UnityEngine.Vector3(clip[at], clip[at + 2], clip[at + 1]);
                }
                float dt = (float)(1.0 / fps * (0.75 + 0.5 * rng.NextDouble()));
                Time.deltaTime = dt;
                now += dt;
                Call(partner, "Update");
                PosePlayback playback = partner.Playback;
                maxQueued = Math.Max(maxQueued, playback.Queued);
                if (double.IsNaN(gapAtFirst) && playback.Queued > 0)
                {
                    fedAtFirst = partner.FramesFed;
                    playheadAtFirst = playback.Playhead;
                    gapAtFirst = fedAtFirst - playheadAtFirst;
                    firstShown = sphere[0].position;
                }
                else if (!double.IsNaN(gapAtFirst) && sphere[0].position.x != firstShown.x)
                {
                    moved = true;
                }
            }
            double gapAtEnd = partner.FramesFed - partner.Playback.Playhead;
            Console.WriteLine(fps + " fps: " + partner.FramesFed + " actor frames fed, playhead "
                + partner.Playback.Playhead.ToString("F1") + ", behind the actor by "
                + gapAtFirst.ToString("F1") + " frames at the first pose and " + gapAtEnd.ToString("F1")
                + " at the end, at most " + maxQueued + " poses held");
            if (maxQueued > 10) { Console.WriteLine("FAILED: " + fps + " fps: " + maxQueued + " poses held"); failed = true; }
            if (gapAtEnd - gapAtFirst > Token) { Console.WriteLine("FAILED: " + fps + " fps: the playback fell behind"); failed = true; }
            if (partner.FramesFed < 60 * 30 - 2) { Console.WriteLine("FAILED: " + fps + " fps: the actor was not fed on the clock"); failed = true; }
            if (!moved) { Console.WriteLine("FAILED: " + fps + " fps: the partner did not move"); failed = true; }
            Call(partner, "OnDestroy");
        }
        Console.WriteLine(failed ? "SOME FAILED" : "ALL PASSED");
        return failed ? 1 : 0;
    }
}
